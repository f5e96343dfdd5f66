"""The argument parser of every command line here: an option that takes one value is given once, by its full name.

:mod:`argparse` keeps the last value of an option given twice, so ``cansim demo --seed 3
whisker --seed 5`` ran with seed 5 and said nothing, and a results folder could hold a run
made with another seed than the one its command line shows first. :class:`CommandParser`
is an :class:`argparse.ArgumentParser` whose options that store one value (``--seed N``,
``--out DIR``; the default action) refuse a second occurrence with a usage error naming
the option:

>>> ap = CommandParser(prog="demo")
>>> _ = ap.add_argument("--seed", type=int, default=0)
>>> ap.parse_args(["--seed", "3"]).seed
3
>>> ap.parse_args(["--seed", "3", "--seed", "5"])  # doctest: +SKIP
usage: demo [-h] [--seed SEED]
demo: error: argument --seed: given twice (3, then 5); give it once

Flags (``store_true``), counters and ``append`` options are not affected: repeating them
means what it always meant. Abbreviated options are not taken (``allow_abbrev=False`` by
default): an abbreviation silently changes meaning when an option is added - the
recognition study's ``--seed 3`` meant ``--seeds 3`` until it had a ``--seed`` of its own.

The commands of :mod:`whisker_io` (``python -m whisker_io.radial``), of ``cansim`` and of its
demos, studies and examples all parse with it. :func:`run_command` runs a script's ``main`` so
that a missing extra ends it with one line naming the extra and status 6
(:data:`EXIT_MISSING_EXTRA`, as ``cansim`` does), not a traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import Any

__all__ = ["CommandParser", "EXIT_MISSING_EXTRA", "run_command"]

#: Exit status of a command whose optional dependency (a pip extra) is not installed.
EXIT_MISSING_EXTRA = 6


def run_command(main: Callable[[], int], prog: str) -> int:
    """``main()``'s status; a :class:`~whisker_io.errors.MissingExtraError` is one line on stderr (``prog: ...``,
    naming the extra) and :data:`EXIT_MISSING_EXTRA`. For a script's ``raise SystemExit(run_command(main, "name"))``."""
    from whisker_io.errors import MissingExtraError

    try:
        return main()
    except MissingExtraError as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return EXIT_MISSING_EXTRA


class _StoreOnce(argparse._StoreAction):
    """argparse's ``store`` action, refusing a second value in the same parse."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        shown = " ".join(map(str, values)) if isinstance(values, list) else str(values)
        seen: dict[int, str] = getattr(parser, "_given_once", None) or {}
        if id(self) in seen:
            raise argparse.ArgumentError(self, f"given twice ({seen[id(self)]}, then {shown}); give it once")
        seen[id(self)] = shown
        parser._given_once = seen  # type: ignore[attr-defined]
        super().__call__(parser, namespace, values, option_string)


class CommandParser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` on which an option storing one value may be given once per command line
    and options are not abbreviated (module docstring); sub-parsers made by :meth:`add_subparsers` are of this
    class too."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)
        self.register("action", None, _StoreOnce)
        self.register("action", "store", _StoreOnce)

    def parse_known_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                         namespace: argparse.Namespace | None = None) -> tuple[argparse.Namespace, list[str]]:
        """As :class:`argparse.ArgumentParser`'s; what this parse has stored is forgotten at its start."""
        self._given_once: dict[int, str] = {}
        return super().parse_known_args(args, namespace)
