"""Models of your own, found by ``"package.module:Class"`` or by an installed package's name.

An installed package registers its models in the ``gva.models`` entry-point group, as pytest
finds its plug-ins; in the package's ``pyproject.toml``::

    [project.entry-points."gva.models"]
    colour-detector = "my_lab.detectors:ColourDetector"

and, once it is ``pip install``-ed, ``--model colour-detector`` finds it. A module that is not
installed is named by path, ``--model my_lab.detectors:ColourDetector``, and must be importable:
on ``sys.path``, e.g. through ``PYTHONPATH``. A built-in model's name always means the built-in.
Nothing here imports torch: the trials of a model without weights never load it.
"""

from __future__ import annotations

import importlib
from importlib import metadata

from perception.errors import InvalidInputError
from perception.interface import PerceptionModel

ENTRY_POINT_GROUP = "gva.models"
"""The entry-point group an installed package registers its models in."""


def installed_models() -> dict[str, metadata.EntryPoint]:
    """The models installed packages register, by name (the first of a repeated name)."""
    found: dict[str, metadata.EntryPoint] = {}
    for entry in metadata.entry_points(group=ENTRY_POINT_GROUP):
        found.setdefault(entry.name, entry)
    return found


def is_class_path(name: str) -> bool:
    """Whether ``name`` has the form ``"package.module:Class"``."""
    return ":" in name


def plugin_class(name: str) -> type[PerceptionModel]:
    """The model class ``"package.module:Class"`` or an installed entry point's name names.

    Raises:
        InvalidInputError: An unknown name, a module that does not import, a missing class or a
            class that is not a :class:`~perception.interface.PerceptionModel`; the message
            says which.

    """
    if is_class_path(name):
        module_name, _, class_name = name.partition(":")
        if not module_name or not class_name.isidentifier():
            raise InvalidInputError("model", name, "'package.module:Class' with both parts")
        target = f"module {module_name!r}"
    else:
        entry = installed_models().get(name)
        if entry is None:
            installed = ", ".join(installed_models()) or "none installed"
            raise InvalidInputError("model", name, "a model name an installed package "
                                    f"registers in {ENTRY_POINT_GROUP!r} ({installed}), or "
                                    "'package.module:Class'")
        module_name, _, class_name = entry.value.partition(":")
        target = f"{ENTRY_POINT_GROUP} entry point {name} = {entry.value!r}: module " \
            f"{module_name!r}"
    try:
        module = importlib.import_module(module_name)
    except Exception as error:  # a plug-in's import may raise anything: one clear line
        hint = " (is its folder on PYTHONPATH, or its package installed?)" if isinstance(
            error, ModuleNotFoundError) and error.name == module_name.partition(".")[0] else ""
        raise InvalidInputError("model", name, f"an importable module; importing {target} "
                                f"raised {type(error).__name__}: {error}{hint}") from error
    cls = getattr(module, class_name, None) if class_name else None
    if cls is None:
        raise InvalidInputError("model", name, f"a class that {target} defines; it has no "
                                f"{class_name!r}")
    if not isinstance(cls, type) or not issubclass(cls, PerceptionModel):
        raise InvalidInputError("model", name, "a subclass of perception.interface."
                                f"PerceptionModel; {class_name} is {cls!r}")
    return cls


def build_plugin(name: str) -> PerceptionModel:
    """A model of the class ``name`` names (:func:`plugin_class`), built with no arguments.

    Raises:
        InvalidInputError: The class cannot be found, has no ``name``, or raised while it was
            built; the message says which, in one line.

    """
    cls = plugin_class(name)
    model_name = getattr(cls, "name", None)
    if not isinstance(model_name, str) or not model_name:
        raise InvalidInputError("model", name, f"a class with a name (class {cls.__name__} "
                                "needs e.g. name = 'my-model')")
    try:
        return cls()
    except Exception as error:  # the constructor is the plug-in's code: one clear line
        raise InvalidInputError("model", name, "a class that builds with no arguments; "
                                f"{cls.__name__}() raised {type(error).__name__}: "
                                f"{error}") from error
