"""The argument parser of every demo, study and example: an option that takes one value is given once.

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
means what it always meant.
"""

from __future__ import annotations

import argparse
import weakref
from typing import Any

__all__ = ["CommandParser"]


class _StoreOnce(argparse._StoreAction):
    """argparse's ``store`` action, refusing a second value in the same parse."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._parse: weakref.ref[argparse.Namespace] | None = None  # the namespace of the parse that stored a value
        self._first: str = ""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        shown = " ".join(map(str, values)) if isinstance(values, list) else str(values)
        if self._parse is not None and self._parse() is namespace:
            raise argparse.ArgumentError(self, f"given twice ({self._first}, then {shown}); give it once")
        self._parse, self._first = weakref.ref(namespace), shown
        super().__call__(parser, namespace, values, option_string)


class CommandParser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` on which an option storing one value may be given once per command line
    (module docstring); sub-parsers made by :meth:`add_subparsers` are of this class too."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.register("action", None, _StoreOnce)
        self.register("action", "store", _StoreOnce)
