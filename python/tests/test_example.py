"""examples/digitise.py runs to its end (so it never rots)."""

import runpy


def test_the_digitise_example_runs(repo, capsys):
    runpy.run_path(str(repo / "examples/digitise.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert "phase table: (3, 181)" in out and "relative standard error on the object" in out
