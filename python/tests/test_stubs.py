"""The type stubs (_hmap.pyi) name what the module binds, and every binding has a docstring or a
stub: an editor completes each name, help() explains it."""

import ast
import inspect
import pathlib

import hmap
from hmap import _hmap

STUBS = pathlib.Path(hmap.__file__).with_name("_hmap.pyi")


def stub_names():
    """{'Map': {'load', 'save', ...}, 'sim': {'Scene', ...}, 'sim.Scene': {...}, '': top-level}."""
    tree = ast.parse(STUBS.read_text())
    names = {}

    def walk(body, prefix):
        mine = names.setdefault(prefix, set())
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                mine.add(node.name)
            if isinstance(node, ast.ClassDef):
                walk(node.body, f"{prefix}.{node.name}".lstrip("."))

    walk(tree.body, "")
    return names


def bound_names(obj):
    return {n for n in dir(obj) if not n.startswith("_") or n == "__init__"} - {"__init__"}


def test_every_binding_has_a_stub():
    stubs = stub_names()
    for scope, obj in (("sim", _hmap.sim), ("pvox", _hmap.pvox), ("io", _hmap.io), ("eval", _hmap.eval),
                       ("slam", _hmap.slam), ("render", _hmap.render)):
        missing = {n for n in bound_names(obj) if not inspect.ismodule(getattr(obj, n))} - stubs[scope]
        assert not missing, f"{scope}: no stub for {sorted(missing)}"
        for name in bound_names(obj):
            member = getattr(obj, name)
            if inspect.isclass(member):
                own = {n for n in vars(member) if not n.startswith("_")}
                missing = own - stubs[f"{scope}.{name}"]
                assert not missing, f"{scope}.{name}: no stub for {sorted(missing)}"


def test_every_class_member_has_a_stub():
    stubs = stub_names()
    for name in ("Params", "Map", "Grid2D", "Mapper", "HybridMapper"):
        own = {n for n in vars(getattr(_hmap, name)) if not n.startswith("_")}
        missing = own - stubs[name]
        assert not missing, f"{name}: no stub for {sorted(missing)}"
    assert {"params_for_scan", "Error", "InputError"} <= stubs[""]


def test_new_bindings_have_docstrings():
    for obj in (_hmap.sim, _hmap.pvox, _hmap.render):
        for name in bound_names(obj):
            member = getattr(obj, name)
            assert member.__doc__ and len(member.__doc__) > 20, f"{obj.__name__}.{name}"
    for cls in (_hmap.sim.Sensor, _hmap.sim.Scene, _hmap.sim.Trajectory, _hmap.pvox.VoxelMap, _hmap.pvox.Mapper):
        for name, member in vars(cls).items():
            if name.startswith("_") or not callable(member):
                continue
            assert member.__doc__ and "(" in member.__doc__, f"{cls.__name__}.{name}"
    for name in ("write_ply", "write_points_ply", "write_pgm", "write_bt", "write_png"):
        assert len(getattr(_hmap.io, name).__doc__) > 60, name
