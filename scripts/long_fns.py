#!/usr/bin/env python3
"""List non-test Rust functions longer than a threshold.

Usage: scripts/long_fns.py [--min N] DIR...

A function's length counts the lines from the line holding `fn` to the line
holding its closing brace, both included. Comments, string, raw-string and
char literals are blanked before braces are matched. Functions inside a
`#[cfg(test)]` item (a `mod tests { ... }`), `#[test]` functions and files
named `tests.rs` or under a `tests/` folder are left out. Nested functions
are listed on their own as well as counted in their parent.
"""

import os
import re
import sys


def blank(src: str) -> str:
    """Replace comments and literals by spaces, keeping newlines."""
    out = []
    i, n = 0, len(src)

    def keep_newlines(s: str) -> str:
        return "".join(c if c == "\n" else " " for c in s)

    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            j = n if j < 0 else j
            out.append(keep_newlines(src[i:j]))
            i = j
        elif src.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if src.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif src.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append(keep_newlines(src[i:j]))
            i = j
        else:
            m = re.match(r'b?r(#*)"', src[i:i + 300])
            prev = src[i - 1] if i else " "
            if m and not (prev.isalnum() or prev == "_"):
                close = '"' + m.group(1)
                j = src.find(close, i + m.end())
                j = n if j < 0 else j + len(close)
                out.append(keep_newlines(src[i:j]))
                i = j
            elif c == '"' or (c == "b" and src.startswith('b"', i)
                              and not (prev.isalnum() or prev == "_")):
                j = i + (2 if c == "b" else 1)
                while j < n and src[j] != '"':
                    j += 2 if src[j] == "\\" else 1
                j += 1
                out.append(keep_newlines(src[i:j]))
                i = j
            elif c == "'":
                # char literal ('a', '\n', '\u{..}', '{') or a lifetime ('a)
                m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'])'", src[i:i + 12])
                if m:
                    out.append(" " * m.end())
                    i += m.end()
                else:
                    out.append(c)
                    i += 1
            else:
                out.append(c)
                i += 1
    return "".join(out)


def match_brace(text: str, open_at: int) -> int:
    depth = 0
    for j in range(open_at, len(text)):
        if text[j] == "{":
            depth += 1
        elif text[j] == "}":
            depth -= 1
            if depth == 0:
                return j
    return len(text) - 1


def item_stop(text: str, start: int):
    """The first `{` or `;` outside brackets from `start`: (position, char),
    or (None, None) at the end of the text."""
    par = 0
    for j in range(start, len(text)):
        ch = text[j]
        if ch in "([":
            par += 1
        elif ch in ")]":
            par -= 1
        elif par == 0 and ch in ";{":
            return j, ch
    return None, None


def item_end(text: str, start: int) -> int:
    """End of the item starting at `start`: its matching `}` or its `;`."""
    j, ch = item_stop(text, start)
    if j is None:
        return len(text) - 1
    return match_brace(text, j) if ch == "{" else j


def functions(path: str):
    src = open(path, encoding="utf-8").read()
    text = blank(src)
    line_of = lambda pos: text.count("\n", 0, pos) + 1
    # Regions excluded: items after #[cfg(test)] and #[test].
    excluded = []
    for m in re.finditer(r"#\[\s*(cfg\(\s*test\s*\)|test)\s*\]", text):
        j = m.end()
        # skip further attributes
        while True:
            k = re.match(r"\s*#\[", text[j:])
            if not k:
                break
            j = text.index("]", j + k.end())  # attributes here are simple
            j += 1
        excluded.append((m.start(), item_end(text, j)))
    for m in re.finditer(r"\bfn\s+([A-Za-z_][A-Za-z0-9_]*)", text):
        pos = m.start()
        if any(a <= pos <= b for a, b in excluded):
            continue
        # its body (none for a declaration ending in `;`)
        body, ch = item_stop(text, m.end())
        if ch != "{":
            continue
        end = match_brace(text, body)
        first, last = line_of(pos), line_of(end)
        yield m.group(1), first, last, last - first + 1


def main(argv):
    minimum = 120
    if argv[:1] == ["--min"]:
        minimum, argv = int(argv[1]), argv[2:]
    rows = []
    for root in argv:
        if os.path.isfile(root):
            walk = [(os.path.dirname(root), [], [os.path.basename(root)])]
        else:
            walk = os.walk(root)
        for dirpath, dirnames, filenames in walk:
            if os.path.basename(dirpath) == "tests":
                continue
            for f in filenames:
                if not f.endswith(".rs") or f == "tests.rs":
                    continue
                p = os.path.join(dirpath, f)
                for name, first, last, length in functions(p):
                    if length > minimum:
                        rows.append((length, p, first, last, name))
    for length, p, first, last, name in sorted(rows, reverse=True):
        print(f"{length:5d}  {p}:{first}-{last}  {name}")


if __name__ == "__main__":
    main(sys.argv[1:])
