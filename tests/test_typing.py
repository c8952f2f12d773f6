"""The public API is typed: every name in ``driftframe.__all__`` is annotated in full, and a game written against
it (the one ``driftframe new`` makes) passes ``mypy --strict`` with driftframe's own annotations (py.typed)."""
import inspect
import os
import shutil
import subprocess
import sys
from pathlib import Path

import driftframe
from driftframe import scaffold

ROOT = Path(__file__).resolve().parent.parent
MAPPED = ("framework", "components", "systems", "demos")    # pyproject.toml's package-dir


def _ours(obj) -> bool:
    return (getattr(obj, "__module__", None) or "").startswith("driftframe")


def _unannotated(qual: str, fn, *, bound: bool) -> list[str]:
    sig = inspect.signature(fn)
    params = list(sig.parameters.values())[1 if bound else 0:]
    out = [f"{qual}({p.name})" for p in params if p.annotation is inspect.Parameter.empty]
    # mypy's rule (disallow_untyped_defs): an __init__ with an annotated parameter returns None implicitly
    if sig.return_annotation is inspect.Signature.empty and not (fn.__name__ == "__init__" and params and not out):
        out.append(f"{qual} -> ?")
    return out


def _public_callables():
    """(qualified name, function, bound) for every public function, and every public method, property and
    constructor of every public class, that driftframe defines (inherited ones from its own bases included)."""
    for name in driftframe.__all__:
        obj = getattr(driftframe, name)
        if inspect.isfunction(obj):
            yield name, obj, False
        elif inspect.isclass(obj):
            for klass in obj.__mro__:
                if not _ours(klass):
                    continue
                for attr, v in vars(klass).items():
                    if attr.startswith("_") and attr != "__init__":
                        continue
                    if "__create_fn__" in getattr(v, "__qualname__", ""):
                        continue                                      # a dataclass's: made from its annotated fields
                    if isinstance(v, staticmethod):
                        yield f"{name}.{attr}", v.__func__, False
                    elif isinstance(v, classmethod):
                        yield f"{name}.{attr}", v.__func__, True
                    elif isinstance(v, property):
                        for f in (v.fget, v.fset):
                            if f is not None:
                                yield f"{name}.{attr}", f, True
                    elif inspect.isfunction(v) and _ours(v):
                        yield f"{name}.{attr}", v, True


def test_every_public_function_method_and_constructor_is_annotated_in_full():
    missing = []
    seen = set()
    for qual, fn, bound in _public_callables():
        if (qual, fn) in seen:
            continue
        seen.add((qual, fn))
        missing += _unannotated(qual, fn, bound=bound)
    assert missing == []
    assert len(seen) > 100                                        # the walk found the API, not nothing


def _installed_layout(dest: Path) -> Path:
    """driftframe laid out as it installs (the package's modules, the mapped folders as its subpackages)."""
    pkg = dest / "driftframe"
    pkg.mkdir(parents=True)
    for src in (ROOT / "driftframe").iterdir():
        if src.suffix in (".py", ".typed"):
            shutil.copy2(src, pkg / src.name)
    for folder in MAPPED:
        (pkg / folder).symlink_to(ROOT / folder, target_is_directory=True)
    return dest


def test_a_new_game_and_the_public_api_pass_mypy_strict(tmp_path):
    site = _installed_layout(tmp_path / "site")
    game = tmp_path / "game"
    game.mkdir()
    scaffold.new("mygame", game)
    # strict in the game and in driftframe/__init__.py; driftframe's other modules are read for their types,
    # their bodies not checked (follow_imports = silent): what a user of an installed copy gets
    env = dict(os.environ, MYPYPATH=str(site))
    res = subprocess.run([sys.executable, "-m", "mypy", "--strict", "--follow-imports", "silent", "--cache-dir",
                          str(tmp_path / "cache"), str(site / "driftframe" / "__init__.py"),
                          str(game / "mygame" / "mygame"), str(game / "mygame" / "tests")],
                         cwd=game / "mygame", capture_output=True, text=True, timeout=240, env=env)
    assert res.returncode == 0, (res.stdout + res.stderr)[-4000:]
