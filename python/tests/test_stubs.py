"""The type stubs describe the native module as built: the same functions and parameters."""
import ast
import inspect
from pathlib import Path

import funcorr
from funcorr import _funcorr

STUB = Path(funcorr.__file__).with_name("_funcorr.pyi")


def stub_functions():
    tree = ast.parse(STUB.read_text())
    return {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}


def test_every_native_function_has_a_stub_with_its_parameters():
    stubs = stub_functions()
    native = {name for name, f in vars(_funcorr).items() if callable(f) and not isinstance(f, type)}
    assert native == set(stubs), (native ^ set(stubs))
    for name, node in stubs.items():
        params = [a.arg for a in node.args.args + node.args.kwonlyargs]
        sig = inspect.signature(getattr(_funcorr, name))
        native_params = [p.name for p in sig.parameters.values() if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)]
        assert params == native_params, name


def test_package_files_are_shipped():
    pkg = Path(funcorr.__file__).parent
    assert (pkg / "py.typed").exists() and STUB.exists()
    for name in funcorr.__all__:
        assert hasattr(funcorr, name), name
