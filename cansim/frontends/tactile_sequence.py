"""Sequence matching of tactile images: place recognition over the last few whisks (Ch.3, Eq 3.1).

Why (measured, ``cansim study ch3``, figure ``ch3_distances.png``): a single 3 x 6 tactile
image of the Ch.3 maze carries little information - on average 2.5-3 of its 18 pixels see
a wall (and, with the Ch.5 contact detection, 46-75 % of the onset images were blank),
open loop + max angle leaves only "contact or not" per pixel - so one image's Eq 3.1
distance to a different place is often as small as to the same place on another pass,
and the nearest stored image (another pass) is the right place for only 58-82 % of the
revisited cycles (20-40 % with the blank onset images); a sequence of 8 raises it to
88-97 %. A run of consecutive
images is far more distinctive: the same place reached again along the same path gives
the same *sequence* of images, a different place rarely does. This front end is the
idea of SeqSLAM (Milford and Wyeth 2012) for the tactile image:

* every whisk cycle's image is stored, in order (the template of cycle ``t`` is its image);
* the dissimilarity of cycle ``t`` to stored cycle ``j`` is the mean Eq 3.1 distance
  (:func:`cansim.frontends.tactile.tactile_similarity`) along the diagonal,
  ``D(t, j) = 1/L sum_k S(I_{t-k}, I_{j-k})``, ``k = 0..L-1`` - the agent moves along
  its path at a constant speed, so the stored sequence advances one cycle per cycle;
* only ``j`` at least ``exclude_recent`` cycles in the past is a candidate (the
  current pass is not a revisit), and only when at least ``min_informative`` of the
  last ``L`` images show a contact: a sequence of blank images matches every other
  blank stretch and says nothing about the place;
* the best ``j`` is a match when ``D <= match_threshold``, it is distinct (below
  ``distinct_ratio`` of any candidate ``distinct_cycles`` or more away) and the match
  continues the previous ones: the best ``j`` of the last ``min_consistent`` cycles
  advanced one cycle per cycle (several consistent matches before a jump, so an
  isolated coincidence never injects energy into the pose cells);
* once matched, the route is followed (``track``): the next cycle takes stored cycle
  ``j + 1`` while its ``D`` stays within the threshold;
* a matched cycle takes the view id of the stored cycle it matched; any other cycle
  gets a new view id. The ids feed RatSLAM's local-view cells (``frontend="ids"``).

The threshold is calibrated from the distributions of ``D`` between the same place
and different places (:func:`calibrate_threshold`), not by a search over the SLAM
metrics. Table 3.1's single-image matcher (:class:`cansim.frontends.tactile.TactileTemplates`)
is close to the special case ``sequence_length=1, min_informative=0, min_consistent=1,
exclude_recent=0, distinct_ratio=1, track=False`` (it stores only unmatched images).

Example
-------
>>> import numpy as np
>>> from cansim.frontends.tactile_sequence import TactileSequenceConfig, TactileSequenceMatcher
>>> rng = np.random.default_rng(0)
>>> route = rng.integers(0, 256, size=(30, 3, 6)).astype(np.uint8)   # 30 distinct places
>>> m = TactileSequenceMatcher(TactileSequenceConfig(sequence_length=4, exclude_recent=10, min_consistent=2))
>>> first = [m.match(img).template_id for img in route]              # first pass: all new
>>> second = [m.match(img).template_id for img in route]             # second pass
>>> second[5:10]                                                     # the same ids as the first pass
[5, 6, 7, 8, 9]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cansim.frontends.store import TemplateMatch
from cansim.frontends.tactile import TACTILE_SHAPE
from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.validation import ConfigDataclass, checked, config_field, validate_fields

__all__ = ["TactileSequenceConfig", "TactileSequenceMatcher", "calibrate_threshold", "sequence_distances"]

_SQRT_LEVELS = np.sqrt(np.arange(256, dtype=np.float64))
_MAX_SEQUENCE = 10_000


@dataclass(frozen=True)
class TactileSequenceConfig(ConfigDataclass):
    """Parameters of :class:`TactileSequenceMatcher`.

    Parameters
    ----------
    sequence_length : int
        ``L``: whisk cycles compared along the diagonal (>= 1; default 8).
    match_threshold : float
        Largest mean Eq 3.1 dissimilarity per image of the sequence counted as a match,
        in sqrt(grey level) (>= 0; default 6; :func:`calibrate_threshold` derives it
        from measured distributions).
    min_informative : int
        Fewest images with a contact (a non-zero pixel) among the last ``L`` for a
        match to be considered (0..``L``; default 4).
    exclude_recent : int
        The most recent cycles that are never candidates (>= 0; default 30, longer
        than an on-the-spot turn and than ``L``).
    min_consistent : int
        Consecutive cycles whose best candidates advanced one cycle per cycle (all
        below the threshold) before a match is reported (>= 1; default 3).
    distinct_ratio : float
        The best candidate must be below this share of the best candidate
        ``distinct_cycles`` or more cycles away (in [0, 1]; 1 = no test; default 0.5).
    distinct_cycles : int
        How far (cycles) a rival candidate must be to count as another place (>= 1; default 5).
    track : bool
        After a confirmed match, the next cycle matches the next stored cycle whenever
        its dissimilarity is within the threshold, without the distinctiveness test and
        the wait (default True): the tests are needed to acquire a place, not to follow
        a route already recognised - along a uniform wall every candidate looks alike.
    """

    sequence_length: int = checked(8, int, minimum=1, maximum=_MAX_SEQUENCE, hint="whisk cycles")
    match_threshold: float = checked(6.0, float, minimum=0, hint="a mean Eq 3.1 dissimilarity in sqrt(level)")
    min_informative: int = 3  # at most sequence_length: checked in __post_init__
    exclude_recent: int = checked(30, int, minimum=0, hint="whisk cycles")
    min_consistent: int = checked(3, int, minimum=1, maximum=_MAX_SEQUENCE, hint="whisk cycles")
    distinct_ratio: float = checked(0.5, float, minimum=0, maximum=1, hint="best / second-best dissimilarity")
    distinct_cycles: int = checked(5, int, minimum=1, maximum=_MAX_SEQUENCE, hint="whisk cycles")
    track: bool = checked(True, bool)

    def __post_init__(self) -> None:
        validate_fields(self)
        config_field(self.min_informative, "min_informative", int, minimum=0, maximum=self.sequence_length,
                     hint="images with a contact among the last sequence_length")


def _check_image(image: ArrayLike) -> NDArray[np.int64]:
    img = np.asarray(image)
    if img.shape != TACTILE_SHAPE:
        raise ShapeError(f"tactile image must have shape {TACTILE_SHAPE} (3 rows x 6 whisker columns), got {img.shape}")
    if not np.issubdtype(img.dtype, np.integer) or img.min() < 0 or img.max() > 255:
        raise InvalidInputError(f"tactile image must hold 8-bit integers 0-255, got dtype {img.dtype}")
    return img.astype(np.int64).ravel()


def _check_images(images: ArrayLike, name: str) -> NDArray[np.int64]:
    arr = np.asarray(images)
    if arr.ndim != 3 or arr.shape[1:] != TACTILE_SHAPE:
        raise ShapeError(f"{name} must have shape (n, 3, 6) (tactile images), got {arr.shape}")
    if arr.size and (not np.issubdtype(arr.dtype, np.integer) or arr.min() < 0 or arr.max() > 255):
        raise InvalidInputError(f"{name} must hold 8-bit integers 0-255, got dtype {arr.dtype}")
    return arr.astype(np.int64).reshape(arr.shape[0], -1)


class TactileSequenceMatcher:
    """Online sequence matching of tactile images (module docstring); one :meth:`match` per whisk cycle.

    Parameters
    ----------
    config : TactileSequenceConfig, optional
    """

    def __init__(self, config: TactileSequenceConfig | None = None) -> None:
        self.config = config if config is not None else TactileSequenceConfig()
        if not isinstance(self.config, TactileSequenceConfig):
            raise InvalidInputError(f"config must be a TactileSequenceConfig, got {type(self.config).__name__}")
        self._images = np.zeros((64, TACTILE_SHAPE[0] * TACTILE_SHAPE[1]), dtype=np.int64)
        self._n_cycles = 0
        self._view_ids: list[int] = []
        self._informative: list[bool] = []
        self._rows: list[NDArray[np.float64]] = []  # Eq 3.1 of the last L images to every stored image
        self._best: list[int] = []  # best candidate of each recent cycle (-1 = none below the threshold)
        self._n_views = 0
        self._track = -1  # stored cycle matched by the previous cycle (-1 = none)

    def __len__(self) -> int:
        """Number of view ids handed out (templates)."""
        return self._n_views

    @property
    def n_cycles(self) -> int:
        """Whisk cycles seen."""
        return self._n_cycles

    def match(self, image: ArrayLike) -> TemplateMatch:
        """Match the image of the next whisk cycle.

        Parameters
        ----------
        image : array (3, 6) of integers in [0, 255]
            Tactile image of the cycle (rows x whisker columns A-F).

        Returns
        -------
        TemplateMatch
            ``template_id`` the view id (that of the matched stored cycle, or a new
            one); ``error`` the mean Eq 3.1 dissimilarity ``D`` of the best candidate
            (``inf`` when there was none).

        Raises
        ------
        ShapeError, InvalidInputError
            Not a (3, 6) array of 8-bit integers; the matcher is unchanged.
        """
        img = _check_image(image)
        cfg = self.config
        t = self._n_cycles
        row = _SQRT_LEVELS[np.abs(self._images[:t] - img)].sum(axis=1)
        if t == self._images.shape[0]:
            self._images = np.concatenate([self._images, np.zeros_like(self._images)])
        self._images[t] = img
        self._n_cycles = t + 1
        self._informative.append(bool(img.any()))
        self._rows.append(row)
        if len(self._rows) > cfg.sequence_length:
            self._rows.pop(0)
        L = cfg.sequence_length
        best, err = -1, math.inf
        last = t - cfg.exclude_recent  # candidates j < last
        if t + 1 >= L and last > L - 1 and sum(self._informative[-L:]) >= cfg.min_informative:
            # D(j) for j = L-1 .. last-1: row of cycle t-k at column j-k
            cand = np.arange(L - 1, last)
            total = np.zeros(cand.size)
            for k in range(L):
                total += self._rows[-1 - k][cand - k]
            total /= L
            nxt = self._track + 1
            if cfg.track and self._track >= 0 and L - 1 <= nxt < last and total[nxt - (L - 1)] <= cfg.match_threshold:
                # following a confirmed match: the next stored cycle continues it (no distinctiveness, no wait)
                self._track = nxt
                self._best.append(nxt)
                if len(self._best) > cfg.min_consistent:
                    self._best.pop(0)
                vid = self._view_ids[nxt]
                self._view_ids.append(vid)
                return TemplateMatch(vid, False, float(total[nxt - (L - 1)]))
            i = int(np.argmin(total))
            far = np.abs(cand - cand[i]) >= cfg.distinct_cycles
            second = float(total[far].min()) if far.any() else math.inf
            distinct = cfg.distinct_ratio >= 1.0 or total[i] < cfg.distinct_ratio * second
            if total[i] <= cfg.match_threshold and distinct:
                best, err = int(cand[i]), float(total[i])
            else:
                err = float(total[i])
        self._best.append(best)
        if len(self._best) > cfg.min_consistent:
            self._best.pop(0)
        recent = self._best
        consistent = best >= 0 and len(recent) == cfg.min_consistent and all(
            recent[-1 - k] == best - k for k in range(cfg.min_consistent))
        self._track = best if consistent else -1
        if consistent:
            vid = self._view_ids[best]
            self._view_ids.append(vid)
            return TemplateMatch(vid, False, err)
        vid = self._n_views
        self._n_views += 1
        self._view_ids.append(vid)
        return TemplateMatch(vid, True, err)

    def match_all(self, images: ArrayLike) -> NDArray[np.int64]:
        """:meth:`match` every image of ``images`` (n, 3, 6) in order; the view ids, (n,)."""
        arr = np.asarray(images)
        _check_images(arr, "images")
        return np.array([self.match(im).template_id for im in arr], dtype=np.int64)


def sequence_distances(images: ArrayLike, sequence_length: int) -> NDArray[np.float64]:
    """Mean Eq 3.1 dissimilarity along the diagonal between every pair of cycles.

    Parameters
    ----------
    images : array (n, 3, 6) of integers in [0, 255]
        Tactile images of consecutive whisk cycles.
    sequence_length : int
        ``L`` >= 1 (1 = Eq 3.1 of the single images).

    Returns
    -------
    ndarray (n, n)
        ``D[t, j] = 1/L sum_k S(I_{t-k}, I_{j-k})``; ``inf`` where ``t`` or ``j`` < ``L - 1``.
    """
    flat = _check_images(images, "images")
    L = config_field(sequence_length, "sequence_length", int, minimum=1, maximum=_MAX_SEQUENCE, hint="whisk cycles")
    n = flat.shape[0]
    single = _SQRT_LEVELS[np.abs(flat[:, None, :] - flat[None, :, :])].sum(axis=2)
    out = np.full((n, n), np.inf)
    if n >= L:
        acc = np.zeros((n - L + 1, n - L + 1))
        for k in range(L):
            acc += single[L - 1 - k : n - k, L - 1 - k : n - k]
        out[L - 1 :, L - 1 :] = acc / L
    return out


def calibrate_threshold(different: ArrayLike, false_match_rate: float = 0.001) -> float:
    """The match threshold from the dissimilarities of different places.

    Parameters
    ----------
    different : array-like
        Sequence dissimilarities ``D`` between different places (finite values, at least one).
    false_match_rate : float
        Accepted share of different-place pairs at or below the threshold, in (0, 1).

    Returns
    -------
    float
        The ``false_match_rate`` quantile of ``different`` (lower interpolation, so at
        most that share of the measured pairs falls below it).
    """
    d = np.asarray(different, dtype=np.float64).ravel()
    d = d[np.isfinite(d)]
    if d.size == 0:
        raise InvalidInputError("different holds no finite dissimilarity; measure different-place pairs first")
    if not (isinstance(false_match_rate, (int, float)) and 0.0 < false_match_rate < 1.0):
        raise InvalidInputError(f"false_match_rate must be in (0, 1), got {false_match_rate!r}")
    return float(np.quantile(d, false_match_rate, method="lower"))
