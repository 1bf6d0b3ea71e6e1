"""The type hints `python/lucent.pyi` against the module as built: every
function of `lucent` has a stub with the same parameters (names, order,
kinds, defaults), read from the function's `__text_signature__` through
`inspect.signature` on one side and from the stub's syntax tree (`ast`) on
the other; the stub declares nothing the module lacks; `Optics` has the
stub's members; and every parameter is documented in the function's
docstring. So the stubs and the docs cannot drift from the signatures."""

import ast
import inspect
import re

import pytest

import lucent

KINDS = {
    "posonly": inspect.Parameter.POSITIONAL_ONLY,
    "args": inspect.Parameter.POSITIONAL_OR_KEYWORD,
    "vararg": inspect.Parameter.VAR_POSITIONAL,
    "kwonly": inspect.Parameter.KEYWORD_ONLY,
    "kwarg": inspect.Parameter.VAR_KEYWORD,
}
NO_DEFAULT = inspect.Parameter.empty


def module_functions():
    return {
        name: f
        for name, f in vars(lucent).items()
        if not name.startswith("_") and callable(f) and not isinstance(f, type)
    }


def stub_module(repo):
    return ast.parse((repo / "python/lucent.pyi").read_text())


def stub_parameters(fn: ast.FunctionDef):
    """(name, kind, default) of a stub's parameters; defaults as values."""
    a = fn.args
    out = []
    positional = a.posonlyargs + a.args
    defaults = [NO_DEFAULT] * (len(positional) - len(a.defaults)) + [ast.literal_eval(d) for d in a.defaults]
    for i, p in enumerate(positional):
        kind = KINDS["posonly"] if i < len(a.posonlyargs) else KINDS["args"]
        out.append((p.arg, kind, defaults[i]))
    if a.vararg:
        out.append((a.vararg.arg, KINDS["vararg"], NO_DEFAULT))
    for p, d in zip(a.kwonlyargs, a.kw_defaults):
        out.append((p.arg, KINDS["kwonly"], NO_DEFAULT if d is None else ast.literal_eval(d)))
    if a.kwarg:
        out.append((a.kwarg.arg, KINDS["kwarg"], NO_DEFAULT))
    return out


def module_parameters(f):
    return [(p.name, p.kind, p.default) for p in inspect.signature(f).parameters.values()]


def test_every_function_has_a_stub_with_its_parameters(repo):
    stubs = {n.name: n for n in stub_module(repo).body if isinstance(n, ast.FunctionDef)}
    functions = module_functions()
    assert len(functions) >= 10, sorted(functions)
    assert sorted(functions) == sorted(stubs), "functions of the module vs lucent.pyi"
    for name, f in functions.items():
        assert f.__text_signature__, f"{name} has no text signature"
        assert module_parameters(f) == stub_parameters(stubs[name]), f"parameters of {name}: module vs lucent.pyi"


def test_the_optics_class_has_the_stub_members(repo):
    cls = next(n for n in stub_module(repo).body if isinstance(n, ast.ClassDef) and n.name == "Optics")
    stub = {n.name for n in cls.body if isinstance(n, ast.FunctionDef)}
    real = {n for n in dir(lucent.Optics) if not n.startswith("_")}
    assert stub == real


@pytest.mark.parametrize("name", sorted(module_functions()))
def test_every_parameter_is_documented(name):
    f = module_functions()[name]
    doc = f.__doc__ or ""
    for p in inspect.signature(f).parameters.values():
        if p.kind == inspect.Parameter.VAR_KEYWORD:
            continue
        assert re.search(rf"\b{p.name}\b", doc), f"{name}: parameter {p.name} is not in its docstring"


def test_a_renamed_keyword_names_the_new_one(repo):
    recipe = repo / "fixtures/samples/IOL1068-09.toml"
    with pytest.raises(TypeError, match="'wavelength': it is called 'wavelength_nm'"):
        lucent.bssrdf(recipe, wavelength=550.0)
    with pytest.raises(TypeError, match="'wavelength': it is called 'wavelength_nm'"):
        lucent.fit(recipe, "x.exr", "weight_percent", wavelength=550.0)
    with pytest.raises(TypeError, match="'wavelength_nm': it is called 'wavelengths_nm'"):
        lucent.optics(recipe, wavelength_nm=[550.0])
    with pytest.raises(TypeError, match="unexpected keyword argument 'colour'"):
        lucent.optics(recipe, colour="red")
