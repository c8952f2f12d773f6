"""mkdocs hook: lay out driftframe as it installs, for mkdocstrings to read.

The subpackages live in folders of other names (pyproject.toml's package-dir: ``framework/`` is
``driftframe.framework``), which griffe's static analysis cannot follow. Before the reference is collected,
this hook lays out ``build/docs-src/driftframe/``: copies of the package's own modules (griffe looks for
subpackages beside the real path of ``__init__.py``, so not links) and links to the four mapped folders;
mkdocs.yml's ``paths`` points the handler there.
"""
from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
TREE = ROOT / "build" / "docs-src"
MAPPED = ("framework", "components", "systems", "demos")


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
