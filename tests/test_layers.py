"""Layers point down only (DESIGN.md): no module imports a package above its own.

Every ``import`` of ``morl_trl.<package>`` in the source, at module level or inside a
function, is checked against the packages that package may use.
"""

import ast
import importlib
import importlib.util
import inspect
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "morl_trl"

# package -> the morl_trl packages it may import (besides itself)
ALLOWED = {
    "preferences": set(),
    "metrics": {"preferences"},
    "data": {"metrics", "preferences"},  # (metrics: the Pareto mathematics, e.g. PCN's non-dominated episodes)
    "envs": set(),
    "transforms": {"envs", "preferences"},
    "gym": {"envs"},
    "objectives": {"preferences", "data"},
    "evaluation": {"envs", "transforms", "metrics", "preferences"},
    "reporting": {"envs", "metrics", "preferences", "evaluation"},
    "runs": {"envs", "metrics", "preferences", "evaluation", "reporting"},
    # the kit every algorithm's loop uses (Agent, optimizer step, capture, the run's parts)
    "training": {"envs", "transforms", "objectives", "data", "metrics", "preferences", "evaluation", "reporting",
                 "runs"},
    # one folder per algorithm (builder, update, on_batch, loop) and the registry
    "algorithms": {"envs", "transforms", "objectives", "data", "metrics", "preferences", "evaluation", "reporting",
                   "runs", "training"},
    # configuration, train / evaluate, policies, the authors' record
    "recipes": {"envs", "transforms", "objectives", "data", "metrics", "preferences", "evaluation", "reporting",
                "runs", "training", "algorithms"},
    "grid": {"envs", "transforms", "objectives", "data", "metrics", "preferences", "evaluation", "reporting", "runs",
             "training", "algorithms", "recipes"},
}


#: modules at the package root every layer may use (they import no morl_trl package)
ROOT_MODULES = {"_torchrl_compat", "_quiet", "_suggest", "_lazy"}


def _imports(path: Path) -> set[str]:
    """The morl_trl sub-packages ``path`` imports (the root modules of ROOT_MODULES left out)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names if node.module == "morl_trl"]
        for name in names:
            parts = name.split(".")
            if parts[0] == "morl_trl" and len(parts) > 1 and parts[1] not in ROOT_MODULES:
                found.add(parts[1])
    return found


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        if len(rel.parts) > 1:
            yield rel.parts[0], path


def test_every_package_is_placed_in_a_layer():
    packages = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert packages == set(ALLOWED), f"place {sorted(packages ^ set(ALLOWED))} in ALLOWED"


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_no_package_imports_a_higher_layer(package):
    bad = {}
    for pkg, path in _modules():
        if pkg != package:
            continue
        up = _imports(path) - ALLOWED[package] - {package}
        if up:
            bad[str(path.relative_to(PACKAGE.parent))] = sorted(up)
    assert not bad, f"{package} may import only {sorted(ALLOWED[package])}; found {bad}"


# ---------------------------------------------------------------------- private names, cycles
def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _resolve(node: ast.ImportFrom, here: str, is_package: bool) -> str | None:
    """The absolute module an ``ImportFrom`` reads from (relative imports resolved)."""
    if node.level == 0:
        return node.module
    base = here.split(".") if is_package else here.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _edges(name: str, path: Path):
    """``(imported module, imported names)`` of every morl_trl import in a module (any depth)."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("morl_trl"):
                    yield a.name, []
        elif isinstance(node, ast.ImportFrom):
            source = _resolve(node, name, path.name == "__init__.py")
            if source and source.startswith("morl_trl"):
                yield source, [a.name for a in node.names]


def _is_private(part: str) -> bool:
    return part.startswith("_") and not part.startswith("__")


def _owner(module: str) -> str | None:
    """The package a private module is private to (what precedes its first ``_name``), or ``None``."""
    parts = module.split(".")
    for i, part in enumerate(parts):
        if _is_private(part):
            return ".".join(parts[:i])
    return None


def test_no_module_imports_another_modules_private_names():
    """``from morl_trl.x import _name`` from another module, or a private module (``_x``) from
    outside the package that holds it, is an error: what two modules share is public (or lives
    in one of them)."""
    bad = []
    for name, path in MODULES.items():
        for source, names in _edges(name, path):
            if source == name:
                continue
            owner = _owner(source)
            if owner is not None and not (name == owner or name.startswith(owner + ".")):
                bad.append(f"{name} imports the private module {source}")
            for n in names:
                if _is_private(n) and f"{source}.{n}" not in MODULES:
                    bad.append(f"{name} imports {source}.{n}")
    assert not bad, "\n".join(bad)


def test_the_private_import_check_knows_whose_private_module_it_is():
    assert _owner("morl_trl.metrics._arrays") == "morl_trl.metrics"
    assert _owner("morl_trl._torchrl_compat") == "morl_trl"
    assert _owner("morl_trl.envs.mario._nes") == "morl_trl.envs.mario"
    assert _owner("morl_trl.metrics.pareto") is None


def _graph() -> dict[str, set[str]]:
    graph = {}
    for name, path in MODULES.items():
        deps = set()
        for source, names in _edges(name, path):
            for n in names or [None]:
                target = f"{source}.{n}" if n and f"{source}.{n}" in MODULES else source
                if target in MODULES and target != name:
                    deps.add(target)
        graph[name] = deps
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_root_modules_import_no_morl_trl_package():
    for name in ROOT_MODULES:
        assert _imports(PACKAGE / f"{name}.py") == set(), f"morl_trl.{name} is below every layer"
        assert not [s for s, _ in _edges(f"morl_trl.{name}", PACKAGE / f"{name}.py")]


def test_the_private_import_check_catches_one(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("from morl_trl.recipes.off_policy import _seed_everything\n")
    assert [(s, n) for s, n in _edges("morl_trl.grid.probe", probe)] == [("morl_trl.recipes.off_policy", ["_seed_everything"])]


def test_the_cycle_finder_finds_cycles():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles():
    """No module imports (at module level or inside a function) one that imports it back,
    directly or through others; a package's ``__init__`` counts as a module."""
    cycles = _cycles(_graph())
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)


# ---------------------------------------------------------------------- TorchRL's private attributes
def _torchrl_private_names() -> set[str]:
    """Every private name TorchRL defines: the attributes its classes set (``self._x =``), its
    methods and module-level names (``def _x``, ``_x =``), read from its installed source."""
    import torchrl

    names = set()
    pattern = re.compile(r"self\.(_[A-Za-z]\w*)\s*(?::[^=\n]*)?=(?!=)|def (_[A-Za-z]\w*)\(|^(_[A-Za-z]\w*)\s*=", re.M)
    for path in Path(torchrl.__file__).parent.rglob("*.py"):
        for groups in pattern.findall(path.read_text(errors="ignore")):
            names.update(n for n in groups if n and not n.startswith("__"))
    return names


#: reviewed uses of a name TorchRL also defines, on an object that is not TorchRL's
NOT_TORCHRL = {
    ("transforms/domain_randomization.py", "_seed"): "morl_trl.envs.ContextSampler's seed (our class)",
    ("runs/plain.py", "_metadata"): "torch's state_dict metadata (an OrderedDict attribute)",
}


def _private_attribute_uses(path: Path, own_classes: set[str]):
    """``(line, name)`` of every ``obj._name`` (and ``getattr/setattr/hasattr(obj, "_name")``) in
    ``path`` on an object other than ``self``, ``cls``, ``super()``, ``type(self)`` or a class of
    morl_trl's own (a subclass reaching its TorchRL base through ``self`` is checked by
    :func:`test_torchrl_private_names_a_subclass_reaches_through_self_are_declared`)."""

    def own(node) -> bool:
        if isinstance(node, ast.Name):
            return node.id in {"self", "cls"} | own_classes
        return isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in {"super", "type"}

    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Attribute) and _is_private(node.attr) and not own(node.value):
            yield node.lineno, node.attr
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
              and node.func.id in {"getattr", "setattr", "hasattr"} and len(node.args) >= 2
              and isinstance(node.args[1], ast.Constant) and isinstance(node.args[1].value, str)
              and _is_private(node.args[1].value) and not own(node.args[0])):
            yield node.lineno, node.args[1].value


def _own_classes() -> set[str]:
    return {n.name for p in MODULES.values() for n in ast.walk(ast.parse(p.read_text())) if isinstance(n, ast.ClassDef)}


def test_torchrl_private_attributes_are_used_only_in_the_adapter_module():
    """``obj._x`` where TorchRL defines ``_x`` is allowed only in morl_trl/_torchrl_compat.py (each
    name there has a test in tests/test_torchrl_compat.py that fails when TorchRL changes it)."""
    torchrl_names, own_classes = _torchrl_private_names(), _own_classes()
    bad = []
    for path in MODULES.values():
        rel = str(path.relative_to(PACKAGE))
        if rel == "_torchrl_compat.py":
            continue
        for line, name in _private_attribute_uses(path, own_classes):
            if name in torchrl_names and (rel, name) not in NOT_TORCHRL:
                bad.append(f"morl_trl/{rel}:{line}: .{name} (a TorchRL private name: go through morl_trl._torchrl_compat)")
    assert not bad, "\n".join(bad)


def test_the_torchrl_private_attribute_check_catches_one(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("def f(buffer, self):\n    a = buffer._sampler\n    b = getattr(buffer, '_sample_unit', None)\n"
                     "    return self._sampler, a, b\n")
    names = _torchrl_private_names()
    assert {"_sampler", "_storage", "_sample_unit", "_rng", "_carrier"} <= names
    assert [(line, n) for line, n in _private_attribute_uses(probe, set()) if n in names] == [(2, "_sampler"),
                                                                                              (3, "_sample_unit")]


# ---------------------------------------------------------------------- ... and through ``self`` in subclasses
_FOREIGN = ("torchrl", "tensordict")
_SETS_ON_SELF = re.compile(r"self\.(_[A-Za-z]\w*)\s*(?::[^=\n]*)?=(?!=)")


def _foreign(cls) -> bool:
    return cls.__module__.split(".")[0] in _FOREIGN


def _defined_by(base: type) -> set[str]:
    """The private names a TorchRL / tensordict class defines: its class attributes and methods, and
    what its methods (properties included) set on ``self``."""
    names = {n for n in vars(base) if _is_private(n)}
    for value in vars(base).values():
        for func in [getattr(value, a, None) for a in ("fget", "fset", "__func__")] + [value]:
            if inspect.isfunction(func):
                try:
                    names.update(_SETS_ON_SELF.findall(inspect.getsource(func)))
                except (OSError, TypeError):
                    continue
    return names


def _subclasses(cls: type) -> set[type]:
    out, todo = set(), [cls]
    while todo:
        c = todo.pop()
        if c not in out:
            out.add(c)
            todo.extend(c.__subclasses__())
    return out


def _self_private_names(node: ast.ClassDef):
    """``(line, name)`` of every ``self._x`` / ``super()._x`` in a class and every ``_x`` its body
    defines (methods, nested classes, class attributes)."""
    for stmt in node.body:
        if isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and _is_private(stmt.name):
            yield stmt.lineno, stmt.name
        elif isinstance(stmt, (ast.Assign, ast.AnnAssign)):
            for target in stmt.targets if isinstance(stmt, ast.Assign) else [stmt.target]:
                if isinstance(target, ast.Name) and _is_private(target.id):
                    yield stmt.lineno, target.id
    for sub in ast.walk(node):
        if isinstance(sub, ast.Attribute) and _is_private(sub.attr) and (
                (isinstance(sub.value, ast.Name) and sub.value.id == "self")
                or (isinstance(sub.value, ast.Call) and isinstance(sub.value.func, ast.Name)
                    and sub.value.func.id == "super")):
            yield sub.lineno, sub.attr


def _undeclared_torchrl_names(module, path: Path, declared: dict[type, tuple[str, ...]]) -> list[str]:
    """The private names of a TorchRL / tensordict base that a class of ``module`` (or a mixin of
    one) overrides or reaches through ``self`` without ``declared[that base]`` naming them."""
    bad = []
    for node in ast.walk(ast.parse(path.read_text())):
        cls = getattr(module, node.name, None) if isinstance(node, ast.ClassDef) else None
        if not inspect.isclass(cls) or cls.__module__ != module.__name__:
            continue
        foreign, allowed = set(), set()
        for sub in _subclasses(cls):
            for base in sub.__mro__:
                if _foreign(base):
                    foreign |= _defined_by(base)
            allowed.update(n for b, names in declared.items() if issubclass(sub, b) for n in names)
        for line, name in sorted(set(_self_private_names(node))):
            if name in foreign and name not in allowed:
                bad.append(f"{path}:{line}: {node.name} reaches TorchRL's private .{name} through self "
                           "(call it through morl_trl._torchrl_compat, or declare the hook in its SUBCLASS_INTERNALS)")
    return bad


def test_torchrl_private_names_a_subclass_reaches_through_self_are_declared():
    """A subclass of a TorchRL / tensordict class (or a mixin of one) that overrides or reads one of
    its private names through ``self`` does so only for names declared in
    ``morl_trl._torchrl_compat.SUBCLASS_INTERNALS`` (each checked by tests/test_torchrl_compat.py);
    any other use goes through a function of that module."""
    from morl_trl._torchrl_compat import SUBCLASS_INTERNALS

    bad = []
    for name, path in MODULES.items():
        if name != "morl_trl._torchrl_compat":
            bad += _undeclared_torchrl_names(importlib.import_module(name), path, SUBCLASS_INTERNALS)
    assert not bad, "\n".join(bad)


def test_the_subclass_check_catches_an_undeclared_torchrl_private_name(tmp_path):
    from torchrl.objectives import LossModule, SACLoss

    probe = tmp_path / "probe_subclass.py"
    probe.write_text(
        "from torchrl.objectives import SACLoss\n"
        "class Mixin:\n"
        "    def a(self):\n"
        "        return self._vmap_qnetworkN0, self._own\n"
        "class Probe(Mixin, SACLoss):\n"
        "    def _forward_value_estimator_keys(self, **kwargs):\n"
        "        return super()._maybe_get_priority_weight, self._alpha\n")
    spec = importlib.util.spec_from_file_location("probe_subclass", probe)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert issubclass(module.Probe, SACLoss)
    found = _undeclared_torchrl_names(module, probe, {LossModule: ("_forward_value_estimator_keys",)})
    assert [line.split(": ")[1].split(" ")[0] + line.split("private ")[1].split(" ")[0] for line in found] == [
        "Mixin._vmap_qnetworkN0", "Probe._alpha", "Probe._maybe_get_priority_weight"]
    assert len(_undeclared_torchrl_names(module, probe, {LossModule: ("_forward_value_estimator_keys", "_alpha",
                                                                       "_maybe_get_priority_weight",
                                                                       "_vmap_qnetworkN0")})) == 0


def _torchrl_private_imports(path: Path) -> list[tuple[int, str]]:
    """``(line, what)`` of every import of a private TorchRL / tensordict module or name."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.split(".")[0] in _FOREIGN
                    and any(_is_private(p) for p in a.name.split("."))]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module and \
                node.module.split(".")[0] in _FOREIGN:
            out += [(node.lineno, f"{node.module}.{a.name}") for a in node.names
                    if any(_is_private(p) for p in node.module.split(".")) or _is_private(a.name)]
    return out


def test_torchrl_private_modules_and_names_are_imported_only_by_the_adapter_module():
    bad = [f"morl_trl/{path.relative_to(PACKAGE)}:{line}: imports {what} (go through morl_trl._torchrl_compat)"
           for name, path in MODULES.items() if name != "morl_trl._torchrl_compat"
           for line, what in _torchrl_private_imports(path)]
    assert not bad, "\n".join(bad)


def test_the_private_torchrl_import_check_catches_one(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("from torchrl.objectives.utils import _vmap_func, distance_loss\n"
                     "import torchrl._utils\nfrom tensordict._td import TensorDict\n"
                     "from torchrl.objectives import SACLoss as _Alias\nimport torch._dynamo\n")
    assert _torchrl_private_imports(probe) == [(1, "torchrl.objectives.utils._vmap_func"), (2, "torchrl._utils"),
                                               (3, "tensordict._td.TensorDict")]
