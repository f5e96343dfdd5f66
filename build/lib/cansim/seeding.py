"""One fixed seed per run of a study, derived from a base seed and the run's identity.

A study that runs many independent simulations (the Ch.5 and Ch.6 studies, through a
process pool or in a loop) gives every run its own generator,
``np.random.default_rng(derive_seed(base, "map", name))``, so that a run's noise does
not depend on which other runs exist, in which order they run or in which process.
The seed is the first 4 bytes (little-endian) of the SHA-256 of the text
``repr((base_seed, parts))``: stable across processes, platforms and Python versions
for the accepted part types (``str``, ``int``, ``float``, ``bool``; numpy scalars are
taken as the Python number they hold, so ``np.int64(3)`` and ``3`` give one seed).
"""

from __future__ import annotations

import hashlib
import math
import numbers

import numpy as np

from cansim.errors import InvalidInputError

__all__ = ["SEED_BITS", "derive_seed"]

#: Bits of a derived seed (the value lies in ``[0, 2**SEED_BITS)``).
SEED_BITS = 32


def _part(value: object, where: str) -> str | int | float | bool:
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        x = float(value)
        if not math.isfinite(x):
            raise InvalidInputError(f"{where} must be finite, got {value!r}")
        return x
    raise InvalidInputError(f"{where} must be a str, int, float or bool (its text must not depend on the process), "
                            f"got {type(value).__name__}")


def derive_seed(base_seed: int, *parts: str | float) -> int:
    """A fixed seed for one run: SHA-256 of the base seed and the run's identity (module docstring).

    Parameters
    ----------
    base_seed : int
        The study's seed (any integer, e.g. its ``--seed``).
    *parts : str, int, float or bool
        What identifies the run, e.g. ``("map", "box")`` or
        ``("sensor", "box", "lsr", True)``; the order matters.

    Returns
    -------
    int
        In ``[0, 2**32)``; equal inputs give equal seeds, any changed part another one
        (with the probability of a 32-bit hash collision).

    Raises
    ------
    InvalidInputError
        A base seed that is not an integer (or is a bool); a part of another type
        (a list, an object: its text could change between processes) or a NaN/inf float.

    Examples
    --------
    >>> derive_seed(0, "map", "box") == derive_seed(0, "map", "box")
    True
    >>> derive_seed(0, "map", "box") != derive_seed(0, "map", "box_stack")
    True
    """
    if isinstance(base_seed, (bool, np.bool_)) or not isinstance(base_seed, numbers.Integral):
        raise InvalidInputError(f"base_seed must be an integer, got {base_seed!r}")
    key = (int(base_seed), tuple(_part(p, f"part {i}") for i, p in enumerate(parts)))
    digest = hashlib.sha256(repr(key).encode()).digest()
    return int.from_bytes(digest[: SEED_BITS // 8], "little")
