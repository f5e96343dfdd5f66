"""Command lines of the bench scripts: ``--help`` prints the script's docstring; anything else they do not take is
a usage error (exit 2), before any timing."""
from __future__ import annotations

import sys
from typing import Callable, Sequence


def script_args(doc: str | None, usage: str, accepts: Callable[[Sequence[str]], bool] = lambda argv: not argv,
                argv: Sequence[str] | None = None) -> list[str]:
    """The script's arguments, once ``--help`` and values it does not take have been dealt with.

    Parameters
    ----------
    doc : str
        The script's docstring (printed by ``--help``).
    usage : str
        One line: how the script is called.
    accepts : callable
        Whether the arguments are ones the script takes (default: none).
    """
    args = list(sys.argv[1:] if argv is None else argv)
    if any(a in ("-h", "--help") for a in args):
        print((doc or usage).strip())
        raise SystemExit(0)
    if not accepts(args):
        print(f"usage: {usage}\n(--help says more; got {' '.join(args)!r})", file=sys.stderr)
        raise SystemExit(2)
    return args
