"""The source's shape (issue 22): sizes a reader can hold, and systems that know each other only through the
world. Read with ast, so the bars keep holding as the code grows.

* no source module over 800 lines; no function over 150 lines, except a compiled kernel (a numba kernel
  is one loop nest the compiler sees whole), which stays under 250;
* no system module imports another system module (a module of ``systems/`` that defines an
  ``esper.Processor``): systems share state through declared resources, components and events, and
  helpers live in modules of functions (``systems/camera_rig.py``, ``systems/readouts.py``);
* one of each small thing: one slerp, one first-bad-row validator (``validate.rows``), one cell lookup
  in the broad phase's grid (``_cell_slot``).
"""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FOLDERS = ("framework", "systems", "components", "driftframe", "demos")
MODULE_LINES, FUNCTION_LINES, KERNEL_LINES = 800, 150, 250
#: The names that compile a function into a numba kernel: driftframe's ``kernel`` (framework/kernels.py),
#: numba's own, and kepler's ``_both`` (numpy and numba twins of one function).
COMPILERS = {"kernel", "njit", "jit", "_both"}


def _sources():
    for folder in FOLDERS:
        yield from sorted((ROOT / folder).rglob("*.py"))


def _name(node) -> str:
    node = node.func if isinstance(node, ast.Call) else node
    return node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")


def _compiled_by_call(tree) -> set[str]:
    """Functions compiled by a call rather than a decorator: ``kernel(...)(f)``, ``kernel(f)``, ``f`` made
    into variants (``variant(f, ...)``: contact_solve's solvers, broadphase_list's build start), and
    ``f.__code__`` rebuilt into a function inside a function that calls ``kernel``."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and _name(node) in COMPILERS:
            out.update(a.id for a in node.args if isinstance(a, ast.Name))
        if isinstance(node, ast.Call) and _name(node) == "variant" and node.args and isinstance(node.args[0], ast.Name):
            out.add(node.args[0].id)
        if isinstance(node, ast.FunctionDef) and any(isinstance(c, ast.Call) and _name(c) in COMPILERS
                                                     for c in ast.walk(node)):
            out.update(a.value.id for a in ast.walk(node) if isinstance(a, ast.Attribute)
                       and a.attr == "__code__" and isinstance(a.value, ast.Name))
    return out


def _functions(path: Path):
    """``(name, first line, lines, is a kernel)`` of every function and method in ``path``."""
    tree = ast.parse(path.read_text(), str(path))
    by_call = _compiled_by_call(tree)
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            kernel = node.name in by_call or any(_name(d) in COMPILERS for d in node.decorator_list)
            yield node.name, node.lineno, node.end_lineno - node.lineno + 1, kernel


def test_no_source_module_is_over_800_lines():
    long = {str(p.relative_to(ROOT)): n for p in _sources() if (n := len(p.read_text().splitlines())) > MODULE_LINES}
    assert long == {}


def test_no_function_is_over_150_lines_and_no_kernel_over_250():
    long = []
    for path in _sources():
        for name, line, n, kernel in _functions(path):
            if n > (KERNEL_LINES if kernel else FUNCTION_LINES):
                long.append(f"{path.relative_to(ROOT)}:{line} {name}: {n} lines{' (kernel)' if kernel else ''}")
    assert long == []


def test_the_kernel_finder_sees_the_kernels_it_exempts():
    """The bars are only as good as the finder: decorated kernels and the solvers compiled from ``_solve``
    are kernels, a plain function is not (else a long plain function would pass under the kernel bar)."""
    kinds = {name: kernel for name, _, _, kernel in _functions(ROOT / "framework" / "contact_solve.py")}
    assert kinds["_solve"] and not kinds["_solver"]
    kinds = {name: kernel for name, _, _, kernel in _functions(ROOT / "framework" / "broadphase_list.py")}
    assert kinds["_grid_pairs"]
    assert not any(kernel for _, _, _, kernel in _functions(ROOT / "framework" / "schedule.py"))


def _defines_system(path: Path) -> bool:
    tree = ast.parse(path.read_text(), str(path))
    return any(isinstance(n, ast.ClassDef) and any(_name(b) == "Processor" for b in n.bases) for n in ast.walk(tree))


def _module_of(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(("driftframe",) + (parts[:-1] if parts[-1] == "__init__" else parts))


def _imported(path: Path):
    """``(line, module)`` of every import in ``path``, lazy ones inside functions too; ``from a import b``
    gives ``a.b`` as well (``b`` may be a module)."""
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.lineno, node.module
            for a in node.names:
                yield node.lineno, f"{node.module}.{a.name}"


def _system_modules() -> dict[str, Path]:
    mods = {}
    for path in sorted((ROOT / "systems").rglob("*.py")):
        mods[_module_of(path)] = path
    return mods


def _package(module: str) -> str:
    """A system's package: ``driftframe.systems.gravity`` for its modules, the module itself otherwise."""
    parts = module.split(".")
    return ".".join(parts[:3])


def test_no_system_module_imports_another_system_module():
    mods = _system_modules()
    systems = {m for m, p in mods.items() if _defines_system(p)}
    assert {"driftframe.systems.render", "driftframe.systems.gravity.system", "driftframe.systems.warp"} <= systems
    bad = []
    for module, path in mods.items():
        for line, name in _imported(path):
            if name in systems and _package(name) != _package(module):
                bad.append(f"{path.relative_to(ROOT)}:{line} imports {name}")
    assert bad == []


def test_the_import_check_would_see_one_system_importing_another(tmp_path):
    """The check above finds what it looks for: a system module importing another, lazily or not."""
    path = tmp_path / "spy.py"
    path.write_text("import esper\n\nclass Spy(esper.Processor):\n    def process(self, dt):\n"
                    "        from driftframe.systems.gravity import system\n"
                    "        from driftframe.systems.render import RenderSystem\n")
    assert _defines_system(path)
    names = {name for _, name in _imported(path)}
    assert {"driftframe.systems.gravity.system", "driftframe.systems.render"} <= names


@pytest.mark.parametrize("module", ["driftframe.systems.camera_rig", "driftframe.systems.readouts"])
def test_the_shared_helpers_of_systems_define_no_system(module):
    assert not _defines_system(_system_modules()[module])


@pytest.mark.parametrize("module", ["driftframe.systems.static_step"])
def test_the_collision_systems_shape_helpers_define_no_system(module):
    """systems/collision.py imports static_step: allowed only while it stays a module of functions."""
    assert not _defines_system(_system_modules()[module])


# -- one of each small thing (issue 22): found with ast, so a second copy fails here -----------------------

def _defs(name: str) -> list[str]:
    return [f"{path.relative_to(ROOT)}" for path in _sources()
            for node in ast.walk(ast.parse(path.read_text(), str(path)))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name == name]


def test_there_is_one_slerp():
    assert _defs("slerp") == ["framework/frame.py"]


def _first_bad_row_checks(path: Path) -> list[str]:
    """Functions that raise a ValueError saying what a value "must be" and take the first index of a mask
    (``np.flatnonzero(bad)[0]``): a first-bad-row validator."""
    out = []
    for f in ast.walk(ast.parse(path.read_text(), str(path))):
        if not isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        says_must = any(isinstance(n, ast.Raise) and isinstance(n.exc, ast.Call) and _name(n.exc) == "ValueError"
                        and "must be" in ast.unparse(n.exc) for n in ast.walk(f))
        first = any(isinstance(n, ast.Subscript) and isinstance(n.value, ast.Call)
                    and _name(n.value) in ("flatnonzero", "nonzero", "argmax", "argwhere")
                    and isinstance(n.slice, ast.Constant) and n.slice.value == 0 for n in ast.walk(f))
        if says_must and first:
            out.append(f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path.name}:{f.name}")
    return out


def test_there_is_one_first_bad_row_validator():
    found = [c for path in _sources() for c in _first_bad_row_checks(path)]
    assert found == ["framework/validate.py:rows"]


def test_the_finder_of_first_bad_row_validators_sees_one(tmp_path):
    path = tmp_path / "spy.py"
    path.write_text("import numpy as np\n\ndef check(x):\n    bad = x < 0\n    if bad.any():\n"
                    "        i = int(np.flatnonzero(bad)[0])\n"
                    "        raise ValueError(f'x[{i}] must be >= 0, got {x[i]}')\n")
    assert _first_bad_row_checks(path) == ["spy.py:check"]


def test_the_broad_phase_has_one_cell_lookup():
    """A sparse grid cell's bucket is ``key * _HASH``'s top bits: only ``_cell_slot`` computes it."""
    path = ROOT / "framework" / "broadphase_list.py"
    tree = ast.parse(path.read_text(), str(path))
    owners = []
    for f in ast.walk(tree):
        if isinstance(f, ast.FunctionDef):
            if any(isinstance(n, ast.BinOp) and isinstance(n.op, ast.Mult)
                   and "_HASH" in {getattr(n.left, "id", None), getattr(n.right, "id", None)} for n in ast.walk(f)):
                owners.append(f.name)
    assert owners == ["_cell_slot"]
    grid = next(f for f in ast.walk(tree) if isinstance(f, ast.FunctionDef) and f.name == "_grid_pairs")
    calls = [_name(n) for n in ast.walk(grid) if isinstance(n, ast.Call)]
    assert calls.count("_cell_slot") == 3 and "_cell_key" in calls       # filing, the stencil, large bodies
