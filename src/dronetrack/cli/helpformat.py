"""How ``--help`` reads: paragraphs that reflow to the terminal's width, and flags
shown without a value placeholder.

Typer prints a docstring's first paragraph as one line and keeps the hard line
breaks of the others, so a paragraph written at 88 columns breaks mid-sentence on
a narrower or wider terminal; and it shows ``<bool>`` beside a flag, which takes no
value.  Every command of the app is built with ``ReadableCommand`` (the app with
``ReadableGroup``), which joins each paragraph's lines and gives flags an empty
placeholder.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

import typer
from typer.core import TyperCommand, TyperGroup, TyperOption

__all__ = ["ReadableCommand", "ReadableGroup", "ReadableTyper", "reflow"]


def reflow(text: str | None) -> str | None:
    """``text`` with each paragraph (blank-line separated) on one line, its spaces
    collapsed: the terminal then wraps it at its own width."""
    if text is None:
        return None
    paragraphs = inspect.cleandoc(text).split("\n\n")
    return "\n\n".join(" ".join(p.split()) for p in paragraphs if p.strip())


def _flags_without_placeholder(params: list[Any]) -> list[Any]:
    """``params`` with every flag's placeholder (typer shows ``<bool>``) emptied."""
    for param in params:
        if isinstance(param, TyperOption) and param.is_flag and param.metavar is None:
            param.metavar = ""
    return params


class ReadableCommand(TyperCommand):
    """A command whose help paragraphs (and epilog's) reflow and whose flags show no
    placeholder."""

    def __init__(
        self, name: str | None, *, help: str | None = None, epilog: str | None = None, **kwargs: Any
    ) -> None:
        super().__init__(name, help=reflow(help), epilog=reflow(epilog), **kwargs)

    def get_params(self, ctx: Any) -> list[Any]:
        return _flags_without_placeholder(super().get_params(ctx))


class ReadableGroup(TyperGroup):
    """The app: its help reflows, its flags show no placeholder."""

    def __init__(self, *, help: str | None = None, **kwargs: Any) -> None:
        super().__init__(help=reflow(help), **kwargs)

    def get_params(self, ctx: Any) -> list[Any]:
        return _flags_without_placeholder(super().get_params(ctx))


class ReadableTyper(typer.Typer):
    """A Typer app whose commands are ``ReadableCommand`` unless told otherwise."""

    def command(  # type: ignore[override]
        self, name: str | None = None, **kwargs: Any
    ) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
        kwargs.setdefault("cls", ReadableCommand)
        return super().command(name, **kwargs)
