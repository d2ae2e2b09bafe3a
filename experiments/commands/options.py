"""Command-line options declared once: one row per option, from which all else is derived.

A command that fills a settings dataclass (``gva reproduce real``, ``gva reproduce sim``) lists
its options as :class:`Option` rows in a :class:`CommandLine`. From that one table come

1. the parser's arguments (:meth:`CommandLine.add_to`), in the table's order (``--help``'s),
   each default read from the settings dataclass field, so it has one home;
2. the settings' keyword arguments from the parsed ``args`` (:meth:`CommandLine.keywords`);
3. the command line the settings stand for (:meth:`CommandLine.line`): written into each run's
   report ("Made by ...") and printed to resume a run, in :attr:`CommandLine.order`.

Options of their own shape (several arguments for one field, a field read from several
options, a value checked against another option) are :class:`Special` rows: they share the
table, its order and the assembly, and bring their own three functions. As in declarative CLI
libraries, the dataclass stays the source of defaults; unlike them, nothing is inferred from
type hints: each row says its parser and its help.
"""

from __future__ import annotations

import argparse
import operator
from collections.abc import Callable
from dataclasses import MISSING, dataclass, fields, replace
from enum import Enum
from typing import Any, Literal

Shown = Literal["always", "changed", "never"]
"""When an option is written in the command line: always, where its value is not the
default's, or never (e.g. ``--workers``: the same results on any machine)."""


def text(value: object) -> str:
    """``value`` as the command line and ``--help`` write it.

    Names and numbers joined by commas, an enum by its value, a float in its shortest form
    (``0.2``, ``5``), a switch ``on`` or ``off``.
    """
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, Enum):
        return str(value.value)
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, tuple):
        return ",".join(text(part) for part in value)
    return str(value)


def same_members(given: Any, default: Any) -> bool:
    """Whether two collections hold the same members in any order (tasks run in the paper's)."""
    return set(given) == set(default)


def default_of(settings: type[Any], path: str) -> Any:
    """The default of the field ``path`` of the dataclass ``settings``: ``seed``, ``check.holdout``.

    A nested path reads the field's default (its factory's value) and then its attribute.
    """
    top, _, rest = path.partition(".")
    spec = {spec.name: spec for spec in fields(settings)}[top]
    if spec.default is not MISSING:
        value = spec.default
    elif spec.default_factory is not MISSING:
        value = spec.default_factory()
    else:
        raise ValueError(f"{settings.__name__}.{top} has no default for its option")
    return operator.attrgetter(rest)(value) if rest else value


@dataclass(frozen=True)
class Option:
    """One option that fills one settings field: its flag, parser, help and command-line text.

    Args:
        flag: The option, ``--train-threads``; its ``args`` attribute is ``train_threads``.
        help: Its ``--help`` line; ``{default}`` stands for the field's default as :func:`text`
            writes it.
        parse: The argparse type (text to value, refusing bad text with a reason); None: text.
        choices: The values allowed: names, or an enum whose values they are (the field then
            holds the enum member). None: any.
        field: The settings field it fills, ``check.holdout`` for a field's field; default: the
            flag's name with underscores.
        shown: When :meth:`CommandLine.line` writes it (:data:`Shown`).
        same: Whether a value is the default's, for ``shown="changed"``; e.g.
            :func:`same_members` where order does not matter.
        metavar: The value's name in ``--help``.
        none_flag: A second flag that sets the field to ``()`` (``--no-robustness``), written
            instead of the option when the field is empty.
        none_help: The ``--help`` line of ``none_flag``.

    A boolean field is a switch: off by default, ``flag`` turns it on; on by default, it is
    also turned off by ``--no-`` and the flag's name (argparse's ``BooleanOptionalAction``).

    """

    flag: str
    help: str
    parse: Callable[[str], Any] | None = None
    choices: tuple[str, ...] | type[Enum] | None = None
    field: str = ""
    shown: Shown = "changed"
    same: Callable[[Any, Any], bool] = operator.eq
    metavar: str | None = None
    none_flag: str = ""
    none_help: str = ""

    @property
    def dest(self) -> str:
        """Its attribute of the parsed ``args``: argparse's name for the flag."""
        return self.flag.removeprefix("--").replace("-", "_")

    @property
    def path(self) -> str:
        """The settings field it fills."""
        return self.field or self.dest

    @property
    def written(self) -> bool:
        """Whether it may be written in the command line."""
        return self.shown != "never"

    def add_to(self, parser: argparse.ArgumentParser, default: Any) -> None:
        """Adds it to ``parser``, with ``default`` (the settings field's)."""
        shown = self.help.replace("{default}", text(default))
        if isinstance(default, bool):
            action = argparse.BooleanOptionalAction if default else "store_true"
            parser.add_argument(self.flag, action=action, default=default, help=shown)
            return
        choices = self.choices
        if isinstance(choices, type):  # an enum: argparse sees (and names) its values
            choices = tuple(member.value for member in choices)
        typed: dict[str, Any] = {} if self.parse is None else {"type": self.parse}
        parser.add_argument(self.flag, **typed, choices=choices, metavar=self.metavar,
                            default=text(default) if choices and default is not None else default,
                            help=shown)
        if self.none_flag:
            parser.add_argument(self.none_flag, dest=self.dest, action="store_const", const=(),
                                help=self.none_help)

    def read(self, args: argparse.Namespace) -> Any:
        """The field's value the parsed ``args`` give (an enum's member for its value)."""
        value = getattr(args, self.dest)
        if isinstance(self.choices, type) and value is not None:
            return self.choices(value)
        return value

    def parts(self, settings: Any) -> list[str]:
        """The command line's words for the field's value in ``settings``; []: none needed."""
        value = operator.attrgetter(self.path)(settings)
        default = default_of(type(settings), self.path)
        if not self.written or (self.shown == "changed" and self.same(value, default)):
            return []
        if isinstance(default, bool):
            return [self.flag if value else f"--no-{self.flag.removeprefix('--')}"]
        if self.none_flag and not value:
            return [self.none_flag]
        return [f"{self.flag} {text(value)}"]


@dataclass(frozen=True)
class Special:
    """Options of their own shape for one settings field, with their own three functions.

    E.g. ``--loop`` and ``--replan-hz``: two arguments, one field, checked together; or the
    repeated ``--model-config MODEL=FILE``, read against ``--models``. Each table says why.

    Args:
        flag: Its first flag: where it stands in :attr:`CommandLine.order`.
        field: The settings field it fills.
        add: Adds its arguments to a parser (their defaults its own).
        read_args: The field's value from the parsed ``args``.
        write: The command line's words for the field's value; None: never written.

    """

    flag: str
    field: str
    add: Callable[[argparse.ArgumentParser], None]
    read_args: Callable[[argparse.Namespace], Any]
    write: Callable[[Any], list[str]] | None = None

    @property
    def path(self) -> str:
        """The settings field it fills."""
        return self.field

    @property
    def written(self) -> bool:
        """Whether it may be written in the command line."""
        return self.write is not None

    def add_to(self, parser: argparse.ArgumentParser, default: Any) -> None:
        """Adds its arguments to ``parser`` (``default`` unused: they know theirs)."""
        self.add(parser)

    def read(self, args: argparse.Namespace) -> Any:
        """The field's value the parsed ``args`` give."""
        return self.read_args(args)

    def parts(self, settings: Any) -> list[str]:
        """The command line's words for the field's value in ``settings``."""
        return [] if self.write is None else self.write(getattr(settings, self.field))


Row = Option | Special


@dataclass(frozen=True)
class CommandLine:
    """A command's options, declared once: its parser, its settings and its command line.

    Args:
        program: The command, ``gva reproduce real``.
        rows: Its options in ``--help`` order (``--out`` and ``--no-progress``, no settings
            fields, go around them: ``arguments.add_reproduce_options``).
        order: The flags in the order :meth:`line` writes them: every written row's, once.
            Run reports already quote lines in this order, which is not ``--help``'s.

    """

    program: str
    rows: tuple[Row, ...]
    order: tuple[str, ...]

    def __post_init__(self) -> None:
        written = sorted(row.flag for row in self.rows if row.written)
        if sorted(self.order) != written:
            raise ValueError(f"{self.program}: the command line's order names "
                             f"{sorted(self.order)}, not the written options {written}")

    def add_to(self, parser: argparse.ArgumentParser, settings: type[Any]) -> None:
        """Adds every option to ``parser``, each default the field's of ``settings``."""
        for row in self.rows:
            row.add_to(parser, None if isinstance(row, Special) else default_of(settings, row.path))

    def keywords(self, args: argparse.Namespace, settings: type[Any]) -> dict[str, Any]:
        """The keyword arguments of ``settings`` that the parsed ``args`` give.

        A nested field (``check.holdout``) replaces its part of the field's default.
        """
        found: dict[str, Any] = {}
        for row in self.rows:
            top, _, rest = row.path.partition(".")
            value = row.read(args)
            found[top] = (replace(found.get(top, default_of(settings, top)), **{rest: value})
                          if rest else value)
        return found

    def line(self, settings: Any, out: object) -> str:
        """The command line of ``settings`` writing to ``out``: running it again resumes."""
        rows = {row.flag: row for row in self.rows}
        parts = [part for flag in self.order for part in rows[flag].parts(settings)]
        return " ".join([self.program, f"--out {out}", *parts])
