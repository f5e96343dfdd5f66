"""OpenRatSLAM visual templates (``LocalViewMatch``): images -> view-template ids.

Processing of one image, as OpenRatSLAM's ``convert_view_to_view_template``
and ``compare``:

1. crop to ``[crop_y_min_px, crop_y_max_px) x [crop_x_min_px, crop_x_max_px)``
   (None = image edge), split into ``Y x X`` blocks (``template_height_blocks`` x
   ``template_width_blocks``) of ``floor(range / size)`` pixels (the remainder is
   ignored) and average each block to a value in [0, 1] (RGB: the mean of the three
   channels);
2. optional global normalisation ``v <- clip(v * normalisation_mean / mean(v), 0, 1)``;
3. optional patch normalisation over a ``(2 p + 1)^2`` neighbourhood, ``p =
   patch_half_width_blocks`` (edge-clamped): ``v <- clip(((v - mean) / std + 3) / 6, 0, 1)``,
   0.5 where std < ``min_patch_std``;
4. compare with the stored templates whose mean is within ``match_threshold + 0.005``:
   sum of absolute differences between the view's central columns
   ``[shift, X - shift)`` and the template's columns ``[o, o + X - 2 shift)`` for
   ``o = 0, step, ..., 2 shift`` (``shift_match_blocks``, ``step_match_blocks``); ``error = min SAD / (X Y - 2 shift Y)``;
   panoramic mode: circular shifts ``o = 0, step, ... < X`` over all columns,
   ``error = min SAD / (X Y)`` and the relative rotation ``o / X * 2 pi`` (wrapped to (-pi, pi]);
5. ``error <= match_threshold`` -> that template, otherwise the view becomes a new template.

Decision on the C++ bug at ``local_view_match.cpp`` ~l.141 (``for (unsigned int i; ...)``
clears the view buffer with an uninitialised index): the view is always
cleared here. ``emulate_uninitialised_clear=True`` reproduces the outcome when
the garbage index skips the clearing (block sums added to the previous view).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from whisker_io.errors import ConfigError, CorruptFileError, InvalidInputError, ShapeError
from cansim.frontends.store import TemplateMatch, TemplateStore
from whisker_io.validation import ConfigDataclass, checked, validate_fields, whole_number

__all__ = ["VisualTemplateConfig", "VisualTemplates"]


def _channels(shape: tuple[int, ...]) -> str:
    """How an image of ``shape`` holds its colour, for messages: grey (H, W) or its channel count."""
    return "grey (H, W)" if len(shape) == 2 else f"{shape[-1]} channels"


@dataclass(frozen=True)
class VisualTemplateConfig(ConfigDataclass):
    """Parameters of :class:`VisualTemplates` (OpenRatSLAM's ``LocalViewMatch``).

    A *block* is one element of the template: the mean of a rectangle of pixels
    (step 1 of the module docstring). OpenRatSLAM's key is given in brackets;
    :mod:`cansim.models.openratslam_config` maps its config files onto these fields.

    Parameters
    ----------
    template_width_blocks, template_height_blocks : int
        Template size in blocks (columns X, rows Y), >= 1. OpenRatSLAM's compiled-in
        default is 1 x 1, which no real config uses; 60 x 10 here [``template_x_size``,
        ``template_y_size``].
    crop_x_min_px, crop_y_min_px : int
        First pixel column / row of the crop (>= 0) [``image_crop_x_min``, ``image_crop_y_min``].
    crop_x_max_px, crop_y_max_px : int or None
        One past the last pixel column / row of the crop; None = the image edge
        [``image_crop_x_max``, ``image_crop_y_max``; -1 there].
    shift_match_blocks : int
        Column shift range +- (blocks) tried when comparing, >= 0 and < X / 2 unless
        panoramic; OpenRatSLAM default 25 [``vt_shift_match``].
    step_match_blocks : int
        Step between tried shifts (blocks), >= 1; default 5 [``vt_step_match``].
    match_threshold : float
        Largest mean absolute difference of the block intensities (in [0, 1]) counted
        as a match (step 5); default 0.03 [``vt_match_threshold``].
    normalisation_mean : float
        Target mean intensity of global normalisation (step 2); 0 = off [``vt_normalisation``].
    patch_half_width_blocks : int
        Half-width ``p`` (blocks) of the ``(2 p + 1)^2`` patch normalisation (step 3);
        0 = off [``vt_patch_normalise``].
    min_patch_std : float
        Patches with a smaller intensity standard deviation become 0.5 (step 3)
        [``vt_min_patch_normalisation_std``].
    panoramic : bool
        Panoramic (circular-shift) matching, which also gives the relative rotation
        [``vt_panoramic``].
    emulate_uninitialised_clear : bool
        Reproduce the C++ uninitialised-index bug outcome (see the module docstring).
    """

    template_width_blocks: int = checked(60, int, minimum=1)
    template_height_blocks: int = checked(10, int, minimum=1)
    crop_x_min_px: int = checked(0, int, minimum=0)
    crop_x_max_px: int | None = checked(None, int, minimum=1, optional=True, hint="None is the image edge")
    crop_y_min_px: int = checked(0, int, minimum=0)
    crop_y_max_px: int | None = checked(None, int, minimum=1, optional=True, hint="None is the image edge")
    shift_match_blocks: int = checked(25, int, minimum=0)
    step_match_blocks: int = checked(5, int, minimum=1)
    match_threshold: float = checked(0.03, float, minimum=0)
    normalisation_mean: float = checked(0.0, float, minimum=0)
    patch_half_width_blocks: int = checked(0, int, minimum=0)
    min_patch_std: float = checked(0.0, float, minimum=0)
    panoramic: bool = checked(False, bool)
    emulate_uninitialised_clear: bool = checked(False, bool)

    def __post_init__(self) -> None:
        validate_fields(self)  # the declared fields; numpy scalars -> Python numbers (saved as JSON with the model)
        for lo, hi in (("crop_x_min_px", "crop_x_max_px"), ("crop_y_min_px", "crop_y_max_px")):
            if getattr(self, hi) is not None and getattr(self, hi) <= getattr(self, lo):
                raise ConfigError(f"{hi} ({getattr(self, hi)}) must be > {lo} ({getattr(self, lo)}): the crop would be empty")
        if not self.panoramic and 2 * self.shift_match_blocks >= self.template_width_blocks:
            raise ConfigError(
                f"shift_match_blocks ({self.shift_match_blocks}) must be < template_width_blocks/2 "
                f"({self.template_width_blocks}/2) so that some columns are compared"
            )


def _cpp_min(a: np.ndarray | float, b: np.ndarray | float) -> np.ndarray:
    """``std::min(a, b)`` elementwise, NaN semantics included: ``b < a ? b : a``."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return np.where(b < a, b, a)


def _cpp_max(a: np.ndarray | float, b: np.ndarray | float) -> np.ndarray:
    """``std::max(a, b)`` elementwise: ``a < b ? b : a`` (so ``max(0, NaN) = 0``)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return np.where(a < b, b, a)


class VisualTemplates:
    """OpenRatSLAM local view matching on camera images (see the module docstring).

    Parameters
    ----------
    config : VisualTemplateConfig, optional
        Parameters (defaults when omitted).
    image_shape : tuple of int, optional
        Expected image shape ``(H, W)`` or ``(H, W, 3)``; taken from the first
        image when omitted. Images of another shape raise :class:`ShapeError`.
    """

    def __init__(self, config: VisualTemplateConfig | None = None, image_shape: tuple[int, ...] | None = None) -> None:
        self.config = config if config is not None else VisualTemplateConfig()
        c = self.config
        self.store = TemplateStore((c.template_height_blocks, c.template_width_blocks))
        self._means = np.zeros(16)
        self.image_shape: tuple[int, ...] | None = None
        self._last_view = np.zeros((c.template_height_blocks, c.template_width_blocks))
        if image_shape is not None:
            try:
                if isinstance(image_shape, (str, bytes)):
                    raise TypeError
                shape = tuple(whole_number(s, "image_shape entries", minimum=1) for s in image_shape)
            except TypeError:
                raise InvalidInputError(f"image_shape must be a tuple of pixel counts, got {image_shape!r}") from None
            self._check_geometry(shape)
            self.image_shape = shape

    def __len__(self) -> int:
        return len(self.store)

    @property
    def means(self) -> np.ndarray:
        """Mean of each stored template, shape (n,) (a copy)."""
        return self._means[: len(self.store)].copy()

    def _crop(self, shape: tuple[int, ...]) -> tuple[int, int, int, int]:
        c = self.config
        x1 = shape[1] if c.crop_x_max_px is None else c.crop_x_max_px
        y1 = shape[0] if c.crop_y_max_px is None else c.crop_y_max_px
        return c.crop_x_min_px, x1, c.crop_y_min_px, y1

    def _check_geometry(self, shape: tuple[int, ...]) -> None:
        if len(shape) not in (2, 3) or (len(shape) == 3 and shape[2] != 3):
            hint = "; drop the alpha channel: image[..., :3]" if len(shape) == 3 and shape[2] == 4 else ""
            raise ShapeError(f"image must have shape (H, W) (grey) or (H, W, 3) (RGB), got {shape}{hint}")
        x0, x1, y0, y1 = self._crop(shape)
        c = self.config
        if not (0 <= x0 < x1 <= shape[1] and 0 <= y0 < y1 <= shape[0]):
            raise ShapeError(f"crop x[{x0}, {x1}) y[{y0}, {y1}) does not fit the image of shape {shape}")
        if (x1 - x0) < c.template_width_blocks or (y1 - y0) < c.template_height_blocks:
            raise ShapeError(
                f"the crop ({x1 - x0} x {y1 - y0} px) is smaller than the template "
                f"({c.template_width_blocks} x {c.template_height_blocks} blocks); use a larger image or a smaller template"
            )

    def view_template(self, image: np.ndarray) -> np.ndarray:
        """Convert an image to the current view template (steps 1-3), shape (Y, X), values in [0, 1].

        Parameters
        ----------
        image : uint8 array (H, W) or (H, W, 3)
            Grey or RGB image.
        """
        img = np.asarray(image)
        if img.dtype != np.uint8:
            given = (" (a single number: a view id? the visual front end takes camera images; a front end of view "
                     "ids is frontend='ids')" if img.ndim == 0 else "")
            raise InvalidInputError(f"image must be a uint8 array (0-255) like OpenRatSLAM's input, got dtype "
                                    f"{img.dtype}{given}")
        shape = tuple(img.shape)
        if self.image_shape is None:
            self._check_geometry(shape)
        elif shape != self.image_shape:
            if shape[:2] == self.image_shape[:2]:  # the same size, other channels: grey (H, W) against RGB (H, W, 3)
                alpha = "; drop the alpha channel: image[..., :3]" if len(shape) == 3 and shape[2] == 4 else ""
                raise ShapeError(f"image shape {shape} has other channels than the first image's {self.image_shape} "
                                 f"({_channels(shape)} against {_channels(self.image_shape)}); give every image as grey "
                                 f"or every image as RGB{alpha}")
            raise ShapeError(f"image shape {shape} differs from the expected {self.image_shape}; resize or crop it first")
        c = self.config
        x0, x1, y0, y1 = self._crop(shape)
        bx, by = (x1 - x0) // c.template_width_blocks, (y1 - y0) // c.template_height_blocks
        crop = img[y0 : y0 + by * c.template_height_blocks, x0 : x0 + bx * c.template_width_blocks].astype(np.float64)
        if crop.ndim == 3:
            crop = crop.sum(axis=2)
            scale = 255.0 * 3.0
        else:
            scale = 255.0
        sums = crop.reshape(c.template_height_blocks, by, c.template_width_blocks, bx).sum(axis=(1, 3))  # exact: integers
        if c.emulate_uninitialised_clear:
            sums = sums + self._last_view
        view = sums / scale / (bx * by)
        if c.normalisation_mean > 0:
            avg = np.cumsum(view.ravel())[-1] / view.size  # sequential sum, as C++
            with np.errstate(divide="ignore", invalid="ignore"):
                view = _cpp_max(0.0, _cpp_min(view * c.normalisation_mean / avg, 1.0))
        if c.patch_half_width_blocks > 0:
            p = c.patch_half_width_blocks
            padded = np.pad(view, p, mode="edge")
            win = np.lib.stride_tricks.sliding_window_view(padded, (2 * p + 1, 2 * p + 1))
            mean = win.mean(axis=(2, 3))
            std = np.sqrt(((win - mean[..., None, None]) ** 2).mean(axis=(2, 3)))
            with np.errstate(divide="ignore", invalid="ignore"):
                z = _cpp_max(0.0, _cpp_min(1.0, ((view - mean) / std + 3.0) / 6.0))
            view = np.where(std < c.min_patch_std, 0.5, z)
        return view

    def match(self, image: np.ndarray) -> TemplateMatch:
        """Match an image against the stored templates, storing it as a new template if none matches.

        Parameters
        ----------
        image : uint8 array (H, W) or (H, W, 3)

        Returns
        -------
        TemplateMatch
        """
        view = self.view_template(image)  # validates before any state changes
        if self.image_shape is None:
            self.image_shape = tuple(np.asarray(image).shape)
        c = self.config
        view_mean = float(np.cumsum(view.ravel())[-1] / view.size)
        n = len(self.store)
        err, best, rel = math.inf, 0, 0.0
        if n:
            from cansim.frontends._sad_numba import sad_compare

            sad, best, off = sad_compare(
                view, self.store._data[:n], self._means[:n], view_mean, c.match_threshold + 0.005,
                c.shift_match_blocks, c.step_match_blocks, bool(c.panoramic),
            )
            if math.isfinite(sad):
                if c.panoramic:
                    err = sad / float(view.size)
                    rel = off / c.template_width_blocks * 2.0 * math.pi
                    if rel > math.pi:
                        rel -= 2.0 * math.pi
                else:
                    err = sad / float(view.size - 2 * c.shift_match_blocks * c.template_height_blocks)
        self._last_view = view
        if err <= c.match_threshold:
            self.store.set_current(int(best))
            return TemplateMatch(int(best), False, float(err), float(rel))
        new_id = self.store.add(view)
        if new_id >= self._means.shape[0]:
            self._means = np.concatenate([self._means, np.zeros(self._means.shape[0])])
        self._means[new_id] = view_mean
        self.store.set_current(new_id)
        return TemplateMatch(new_id, True, float(err), 0.0)

    # ---------------------------------------------------------------- state
    def to_arrays(self, prefix: str = "vt_") -> dict[str, Any]:
        """State as named arrays for an ``.npz`` file (bit exact)."""
        out = self.store.to_arrays(prefix)
        out[f"{prefix}means"] = self.means
        out[f"{prefix}last_view"] = self._last_view.copy()
        out[f"{prefix}image_shape"] = np.array(self.image_shape if self.image_shape else (), dtype=np.int64)
        return out

    def from_arrays(self, arrays: dict[str, np.ndarray], prefix: str = "vt_") -> None:
        """Restore the state written by :meth:`to_arrays`."""
        for key in (f"{prefix}means", f"{prefix}last_view", f"{prefix}image_shape"):
            if key not in arrays:
                raise CorruptFileError("missing", field=key)
        store = TemplateStore(self.store.shape)
        store.from_arrays(arrays, prefix)
        means = np.asarray(arrays[f"{prefix}means"], dtype=np.float64)
        if means.shape != (len(store),):
            raise CorruptFileError(f"shape {means.shape}, expected ({len(store)},)", field=f"{prefix}means")
        self.store = store
        self._means = np.concatenate([means, np.zeros(16)])
        self._last_view = np.array(arrays[f"{prefix}last_view"], dtype=np.float64)
        shape = tuple(int(s) for s in np.asarray(arrays[f"{prefix}image_shape"]).tolist())
        self.image_shape = shape if shape else None
