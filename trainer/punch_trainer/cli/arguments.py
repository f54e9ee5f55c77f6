"""Command-line options generated from an `*Args` dataclass: one `--flag-name` per field, its `--help` the
field's docstring (the string right below it), its default the field's own, so each lives in one place.

Types map as argparse would write them by hand: `int`, `float`, `str`, `Path` (and `X | None`, whose default
None means "see the help"); `bool` is a switch; `Literal[...]` gives choices; `list[X]` takes one or more
values. A field without a default is a required option. Every value is checked against its bounds
(`punch_trainer/options.py`, stated in the help) before a command starts.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import textwrap
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, ClassVar, Protocol, TypeVar

from punch_trainer.errors import PunchError
from punch_trainer.options import check_options, field_bounds


class DataclassType(Protocol):
    __dataclass_fields__: ClassVar[dict[str, Any]]


ArgsT = TypeVar("ArgsT", bound=DataclassType)


class ArgumentsError(TypeError):
    """A dataclass field has a type that no command-line option can hold (a bug in the dataclass, not user input)."""


def field_docs(args_type: type) -> dict[str, str]:
    """Each field's docstring: the string literal that follows its annotated assignment in the class body."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(args_type)))
    body = next(node for node in tree.body if isinstance(node, ast.ClassDef)).body
    docs = {}
    for node, following in zip(body, body[1:], strict=False):
        if (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and isinstance(following, ast.Expr)
                and isinstance(following.value, ast.Constant) and isinstance(following.value.value, str)):
            docs[node.target.id] = " ".join(inspect.cleandoc(following.value.value).split())
    return docs


def _without_none(annotation: Any) -> Any:
    """`X | None` -> X; anything else as it is."""
    if isinstance(annotation, types.UnionType) or typing.get_origin(annotation) is typing.Union:
        members = [member for member in typing.get_args(annotation) if member is not type(None)]
        if len(members) == 1:
            return members[0]
    return annotation


def _default(field: dataclasses.Field[Any]) -> Any:
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    return dataclasses.MISSING


def add_dataclass_arguments(parser: argparse.ArgumentParser, args_type: type[DataclassType], *, exclude: Iterable[str] = (),
                            value_parsers: Mapping[str, Callable[[str], Any]] | None = None,
                            default_notes: Mapping[str, str] | None = None) -> None:
    """Adds an option for every field of `args_type` except those in `exclude`. `value_parsers`: a field's own
    parser for its text (e.g. `0:1:0.1` for a list of sigmas); `default_notes`: what a default of None means,
    where the help should say more than the docstring does (a default that depends on another option)."""
    docs = field_docs(args_type)
    hints = typing.get_type_hints(args_type)
    value_parsers, default_notes = value_parsers or {}, default_notes or {}
    excluded = set(exclude)
    for field in dataclasses.fields(args_type):
        if field.name in excluded:
            continue
        flag = "--" + field.name.replace("_", "-")
        default = _default(field)
        annotation = _without_none(hints[field.name])
        options: dict[str, Any] = {"dest": field.name}
        if default is dataclasses.MISSING:
            options["required"] = True
        else:
            options["default"] = default
        if field.name in value_parsers:
            options["type"] = _usage_errors(value_parsers[field.name])
        elif annotation is bool:
            options["action"] = "store_true"
        elif typing.get_origin(annotation) is typing.Literal:
            choices = typing.get_args(annotation)
            options.update(type=type(choices[0]), choices=choices)
        elif typing.get_origin(annotation) is list:
            (item,) = typing.get_args(annotation)
            options.update(type=item, nargs="+")
        elif annotation in (int, float, str, Path):
            options["type"] = annotation
        else:
            raise ArgumentsError(f"{args_type.__name__}.{field.name}: no command-line option for the type {hints[field.name]}")
        help_text = docs.get(field.name, "")
        limits = field_bounds(field)
        if limits is not None and (annotation is not str or field.name == "grid") and typing.get_origin(annotation) is not typing.Literal:
            help_text += f" ({limits.describe(typing.get_origin(annotation) in (list, tuple))})"
        if field.name in default_notes:
            help_text += f" (default: {default_notes[field.name]})"
        elif default is not None and default is not dataclasses.MISSING and not isinstance(default, bool) and default != "":
            shown = ",".join(map(str, default)) if isinstance(default, list | tuple) else default
            help_text += f" (default: {shown})"
        options["help"] = help_text.strip().replace("%", "%%")  # argparse formats help with %
        parser.add_argument(flag, **options)


def dataclass_from_arguments(args_type: type[ArgsT], namespace: argparse.Namespace) -> ArgsT:
    """The dataclass of the parsed options (fields left out of the parser keep their defaults)."""
    values = {field.name: getattr(namespace, field.name) for field in dataclasses.fields(args_type) if hasattr(namespace, field.name)}
    args = args_type(**values)
    check_options(args)
    return args


def _usage_errors(parse: Callable[[str], Any]) -> Callable[[str], Any]:
    """A field's own parser whose refusals argparse reports as a usage error (one line), not a traceback."""
    def parse_or_refuse(text: str) -> Any:
        try:
            return parse(text)
        except PunchError as error:
            raise argparse.ArgumentTypeError(str(error)) from None

    parse_or_refuse.__name__ = getattr(parse, "__name__", "value")
    return parse_or_refuse
