"""The type stubs (`cassi/_cassi.pyi`) name every parameter the compiled functions take, in
their order: an editor's completion and a type checker read the stubs, not the binary, so a
parameter the stubs miss is one a user does not see (`search_rows` was missing until stop 45)."""
import ast
import inspect
from pathlib import Path

import cassi._cassi as native

STUBS = Path(__file__).resolve().parents[1] / "cassi" / "_cassi.pyi"


def stub_parameters():
    """{name: [parameter lists, one per overload]} for the stubs' module functions and
    Operator's constructor (without self)."""
    tree = ast.parse(STUBS.read_text())
    out = {}

    def names(fn):
        a = fn.args
        listed = [p.arg for p in a.posonlyargs + a.args + a.kwonlyargs]
        if a.vararg:
            listed.append("*" + a.vararg.arg)
        if a.kwarg:
            listed.append("**" + a.kwarg.arg)
        return [n for n in listed if n != "self"]

    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            out.setdefault(node.name, []).append(names(node))
        elif isinstance(node, ast.ClassDef) and node.name == "Operator":
            for item in node.body:
                if isinstance(item, ast.FunctionDef) and item.name == "__init__":
                    out.setdefault("Operator", []).append(names(item))
    return out


def runtime_parameters(obj):
    listed = []
    for p in inspect.signature(obj).parameters.values():
        prefix = {p.VAR_POSITIONAL: "*", p.VAR_KEYWORD: "**"}.get(p.kind, "")
        listed.append(prefix + p.name)
    return listed


def test_the_stubs_name_every_parameter_in_order():
    stubs = stub_parameters()
    checked = 0
    for name in dir(native):
        obj = getattr(native, name)
        if getattr(obj, "__text_signature__", None) is None:
            continue
        assert name in stubs, f"{name} has no stub"
        want = runtime_parameters(obj)
        if len(stubs[name]) == 1:
            assert stubs[name][0] == want, f"{name}: stub {stubs[name][0]} vs binary {want}"
        else:  # overloads: each names a subset in order, together all of them
            for got in stubs[name]:
                assert got == [p for p in want if p in got], f"{name}: overload {got} vs {want}"
            assert {p for got in stubs[name] for p in got} == set(want), f"{name}: {stubs[name]}"
        checked += 1
    assert checked >= 10, checked


def test_the_stubs_list_every_public_member_of_the_classes():
    tree = ast.parse(STUBS.read_text())
    classes = [n for n in tree.body if isinstance(n, ast.ClassDef)]
    classes = [n for n in classes if n.name in ("Operator", "Calibration")]
    assert len(classes) == 2, [n.name for n in classes]
    for node in classes:
        stubbed = {i.name for i in node.body if isinstance(i, ast.FunctionDef)}
        stubbed = {n for n in stubbed if not n.startswith("_")}
        runtime = {n for n in dir(getattr(native, node.name)) if not n.startswith("_")}
        assert stubbed == runtime, f"{node.name}: stubs {sorted(stubbed)} vs binary {sorted(runtime)}"
