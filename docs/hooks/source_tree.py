"""mkdocs hook: lay out driftframe as it installs, for mkdocstrings to read.

The subpackages live in folders of other names (pyproject.toml's package-dir: ``framework/`` is
``driftframe.framework``), which griffe's static analysis cannot follow. Before the reference is collected,
this hook lays out ``build/docs-src/driftframe/``: copies of the package's own modules (griffe looks for
subpackages beside the real path of ``__init__.py``, so not links) and links to the four mapped folders;
mkdocs.yml's ``paths`` points the handler there. Hooks run after the plugins by default, and mkdocstrings drops
a ``paths`` entry that does not exist yet when its own ``on_config`` runs, so this one runs first (priority 100):
on a fresh clone the tree does not exist before the first build.
"""
from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from mkdocs.plugins import event_priority

ROOT = Path(__file__).resolve().parents[2]
TREE = ROOT / "build" / "docs-src"
MAPPED = ("framework", "components", "systems", "demos")


@event_priority(100)                # before mkdocstrings' on_config (default 0)
def on_config(config: Any) -> Any:
    pkg = TREE / "driftframe"
    if TREE.exists():
        shutil.rmtree(TREE)
    pkg.mkdir(parents=True)
    for src in (ROOT / "driftframe").iterdir():
        if src.suffix in (".py", ".typed"):
            shutil.copy2(src, pkg / src.name)    # a copy: griffe finds subpackages beside the real path of __init__.py
    for folder in MAPPED:
        (pkg / folder).symlink_to(ROOT / folder, target_is_directory=True)
    return config
