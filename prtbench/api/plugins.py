"""Discovery of method plug-ins: a method family is a folder with a light ``spec.py``.

A *method package* (the built-in one is ``methods``, named once in ``pyproject.toml`` under the
entry-point group ``prtbench.method_packages``) holds one folder per family. A folder with an
``__init__.py`` and a ``spec.py`` declares its methods there::

    # methods/vertex/spec.py
    from prtbench.api.plugins import MethodSpec

    METHODS = (
        MethodSpec("vertex", ".diffuse:VertexPRT",
                   "Sloan 2002 diffuse transfer vectors at vertices, shaded per vertex"),
    )

The target is ``"module:Class"``, relative (leading dot) to the family's package; the summary
is the one line ``prtbench list methods`` prints, read without importing the method's code.
So a new folder ``methods/foo/`` with a spec appears in ``prtbench list methods``,
``prtbench describe foo`` and ``prtbench run --method foo`` with no other file edited. A spec
module imports nothing but this module (and the family's light ``__init__``).

Methods from other distributions register through the entry-point group ``prtbench.methods``
(``name = "module:Class"``) instead; see ``docs/ADDING_A_METHOD.md``.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Iterator
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from prtbench.api.errors import PrtbenchError

#: Entry-point group naming the packages whose family folders hold ``spec.py`` modules.
METHOD_PACKAGES_GROUP = "prtbench.method_packages"
#: The module a family folder declares its methods in.
SPEC_MODULE = "spec"


@dataclass(frozen=True)
class MethodSpec:
    """One method of a family: its registered name, class and one-line summary.

    Attributes
    ----------
    name : str
        The registered name (``prtbench run --method NAME``); the class's ``name`` must agree.
    target : str
        ``"module:Class"``; a leading dot is relative to the family's package.
    summary : str
        One line for ``prtbench list methods`` and ``prtbench describe``.
    """

    name: str
    target: str
    summary: str


def method_packages() -> list[str]:
    """Importable names of the method packages (entry-point group ``prtbench.method_packages``)."""
    return sorted({ep.value for ep in metadata.entry_points(group=METHOD_PACKAGES_GROUP)})


def family_folders(package: str) -> Iterator[tuple[str, Path]]:
    """``(module name, folder)`` of every family folder of ``package`` that has a spec module."""
    found = importlib.util.find_spec(package)
    if found is None or not found.submodule_search_locations:
        raise PrtbenchError(f"method package '{package}' (entry point group "
                            f"{METHOD_PACKAGES_GROUP}) cannot be found; accepted: an importable "
                            "package whose folders hold spec.py modules")
    for location in found.submodule_search_locations:
        for folder in sorted(Path(location).iterdir()):
            if ((folder / f"{SPEC_MODULE}.py").is_file() and (folder / "__init__.py").is_file()
                    and folder.name.isidentifier()):
                yield f"{package}.{folder.name}", folder


def method_specs() -> Iterator[tuple[str, str, str]]:
    """``(name, "module:Class", summary)`` of every method declared by a family's spec."""
    for package in method_packages():
        for module_name, folder in family_folders(package):
            module = importlib.import_module(f"{module_name}.{SPEC_MODULE}")
            specs = getattr(module, "METHODS", None)
            if not isinstance(specs, (tuple, list)) or not all(
                    isinstance(s, MethodSpec) for s in specs):
                raise PrtbenchError(f"{folder / (SPEC_MODULE + '.py')}: METHODS must be a tuple "
                                    "of prtbench.api.plugins.MethodSpec")
            for spec in specs:
                target = spec.target
                if target.startswith("."):
                    target = module_name + target
                yield spec.name, target, spec.summary
