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
that a missing extra or bad input ends it with one line and the status ``cansim`` gives it
(:func:`error_status`: 6 for a missing extra, 3 for bad input), not a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any

__all__ = ["CommandParser", "EXIT_BAD_INPUT", "EXIT_FAILED", "EXIT_INTERNAL", "EXIT_INTERRUPTED", "EXIT_MISSING_EXTRA",
           "error_status", "report_error", "run_command"]

#: Exit status of a command that ended on an error nobody foresaw (a bug: its traceback is shown).
EXIT_INTERNAL = 1
#: Exit status of a command given bad input: a malformed or missing file, a value out of range, a bad configuration.
EXIT_BAD_INPUT = 3
#: Exit status of a command that could not finish for another reason the project names (its own errors, the system's).
EXIT_FAILED = 4
#: Exit status of a command whose optional dependency (a pip extra) is not installed.
EXIT_MISSING_EXTRA = 6
#: Exit status of a command stopped by Ctrl-C (``KeyboardInterrupt``), as ``cansim``'s.
EXIT_INTERRUPTED = 130


def error_status(exc: BaseException) -> tuple[int, str]:
    """The exit status and the one-line message of a command that ended on ``exc``.

    One classification for ``cansim`` and for the scripts :func:`run_command` runs: the
    user's input (:class:`~whisker_io.errors.ConfigError`, :class:`~whisker_io.errors.InvalidInputError`,
    :class:`~whisker_io.errors.CorruptFileError`, a missing file) is :data:`EXIT_BAD_INPUT`; a missing
    extra :data:`EXIT_MISSING_EXTRA`; the project's other errors and the system's (``OSError``,
    ``RuntimeError``) :data:`EXIT_FAILED`; anything else :data:`EXIT_INTERNAL`.

    Returns
    -------
    (int, str)
        The status and the message (whitespace folded to single spaces: one line).
    """
    from whisker_io.errors import CansimError, ConfigError, CorruptFileError, InvalidInputError, MissingExtraError

    if isinstance(exc, (ConfigError, InvalidInputError, CorruptFileError)):
        code, message = EXIT_BAD_INPUT, str(exc)
    elif isinstance(exc, MissingExtraError) or (isinstance(exc, ImportError)  # cansim's BackendUnavailableError too
                                                 and (isinstance(exc, CansimError) or "pip install" in str(exc))):
        code, message = EXIT_MISSING_EXTRA, str(exc)
    elif isinstance(exc, FileNotFoundError):
        code, message = EXIT_BAD_INPUT, f"{exc.filename or exc}: no such file or folder"
    elif isinstance(exc, (CansimError, OSError, RuntimeError)):
        code, message = EXIT_FAILED, f"{type(exc).__name__}: {exc}"
    else:
        code, message = EXIT_INTERNAL, f"{type(exc).__name__}: {exc}"
    return code, " ".join(message.split())


def run_command(main: Callable[[], int], prog: str) -> int:
    """``main()``'s status, or the status :func:`error_status` gives the error it ended on, said in one line on stderr.

    For a script's ``raise SystemExit(run_command(main, "name"))``: a missing extra is
    ``prog: ...`` naming the extra (:data:`EXIT_MISSING_EXTRA`), bad input ``prog: error: ...``
    (:data:`EXIT_BAD_INPUT`), as ``cansim`` ends on them, never a traceback. An error
    :func:`error_status` does not know (:data:`EXIT_INTERNAL`, a bug) is raised as it is,
    with its traceback; so is a failure (:data:`EXIT_FAILED`: an ``OSError``, a ``RuntimeError``) when the
    environment sets ``CANSIM_DEBUG`` (``cansim --debug``'s counterpart). Ctrl-C is ``prog: interrupted`` and
    :data:`EXIT_INTERRUPTED`, as ``cansim`` ends on it.
    """
    try:
        return main()
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:
        code = error_status(exc)[0]
        if code == EXIT_INTERNAL or (code == EXIT_FAILED and os.environ.get("CANSIM_DEBUG")):
            raise
        return report_error(exc, prog)


def report_error(exc: BaseException, prog: str) -> int:
    """Say ``exc`` in one line on stderr as the command ``prog`` ends on it (``prog: ...`` naming a missing extra,
    ``prog: error: ...`` otherwise) and return its status (:func:`error_status`)."""
    code, message = error_status(exc)
    print(f"{prog}: {message}" if code == EXIT_MISSING_EXTRA else f"{prog}: error: {message}", file=sys.stderr)
    return code


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
