"""Every figure the library writes is readable without its code (issue 21, item 4).

:func:`figure_problems` checks a matplotlib figure for what a reader needs: every axes that
draws data has labelled x and y (and z) axes that say their unit in brackets (or say they
are a count, index, fraction ...), every colour bar is labelled, every line / marker style
that is drawn is explained (a legend entry, or the only style on its axes), no error bar
is drawn with zero length everywhere, and the figure says what it shows (a title).
:func:`assert_readable_figure` raises with the list. The tests below build the library's
figures on small inputs and apply it; the slow ones (whole quick studies) are marked.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from matplotlib.collections import Collection  # noqa: E402
from matplotlib.colors import to_hex  # noqa: E402
from matplotlib.container import ErrorbarContainer  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.ticker import FixedFormatter  # noqa: E402

#: words that make a label without a bracketed unit acceptable: the quantity is a count,
#: an index, a ratio or a category, and the label says so
UNITLESS = ("count", "index", "id", "number", "fraction", "share", "ratio", "rank", "iteration",
            "whisk", "object", "identity", "strategy", "bin", "probability", "r^2", "rate", "gain",
            "confidence", "coefficient", "dimensionless", "no unit", "scaled", "normalised", "of total",
            "runs", "views", "component", "feature", "model")


def _has_unit(label: str) -> bool:
    low = label.lower()
    return bool(re.search(r"[(\[].+[)\]]", label)) or any(re.search(rf"\b{re.escape(w)}", low) for w in UNITLESS)


def _is_categorical(axis) -> bool:
    """True when the ticks name categories (object names, strategies), not numbers."""
    fmt = axis.get_major_formatter()
    if type(fmt).__name__ == "StrCategoryFormatter":
        return True
    if isinstance(fmt, FixedFormatter):
        return any(re.search(r"[A-Za-z]", str(s)) for s in fmt.seq)
    return False


def _is_colorbar(ax) -> bool:
    return getattr(ax, "_colorbar", None) is not None


def _data_artists(ax) -> list:
    out = [a for a in (*ax.lines, *ax.collections, *ax.patches, *ax.images) if a.get_visible()
           and not (isinstance(a, Line2D) and len(a.get_xdata()) == 0)]  # an empty line draws nothing
    return [a for a in out if not (isinstance(a, Patch) and a is ax.patch)]


def _label_of(ax, other_attr: str) -> str:
    """The axis label, or the label of an axes that shares this axis (a shared x below)."""
    own = getattr(ax, other_attr)()
    if own.strip():
        return own
    group = ax.get_shared_x_axes() if other_attr == "get_xlabel" else ax.get_shared_y_axes()
    for sib in group.get_siblings(ax):
        text = getattr(sib, other_attr)()
        if text.strip():
            return text
    return ""


def _style(artist) -> tuple | None:
    """What a reader tells this artist apart by (colour, marker, line style), or None for fills."""
    try:
        if isinstance(artist, Line2D):
            marker = artist.get_marker()
            marker = "None" if marker in ("", " ", None, "None", "none") else str(marker)
            return ("line", to_hex(artist.get_color()), marker, artist.get_linestyle())
        if isinstance(artist, Collection):
            if artist.get_array() is not None:
                return None  # colour-mapped: explained by a colour bar (checked separately)
            fc = artist.get_facecolor()
            ec = artist.get_edgecolor()
            colour = to_hex(fc[0]) if len(fc) else (to_hex(ec[0]) if len(ec) else "none")
            return ("collection", type(artist).__name__, colour)
        if isinstance(artist, Patch):
            fc = artist.get_facecolor()
            if artist.get_fill() and fc[3] > 0:
                return ("patch", to_hex(fc), artist.get_hatch() or "")
            return ("patch", to_hex(artist.get_edgecolor()), artist.get_hatch() or "")
    except (ValueError, IndexError):
        return None
    return None


def _legends(fig) -> list:
    """Every legend of the figure: a style explained once serves every panel (shared colours)."""
    return [leg for leg in (*(a.get_legend() for a in fig.axes), *fig.legends) if leg is not None]


def _legend_labels(fig) -> set[str]:
    labels: set[str] = set()
    for leg in _legends(fig):
        labels |= {t.get_text() for t in leg.get_texts()}
    return labels


def _legend_keys(fig) -> tuple[set, set]:
    """(colour, marker) of every legend line handle, and every handle colour."""
    pairs, colours = set(), set()
    for leg in _legends(fig):
        for h in leg.legend_handles:
            s = _style(h) if h is not None else None
            if s is None:
                continue
            colours.add(s[1] if s[0] == "line" else s[2] if s[0] == "collection" else s[1])
            if s[0] == "line":
                pairs.add((s[1], s[2]))
                if h.get_markerfacecolor() is not None and s[2] != "None":
                    pairs.add((to_hex(h.get_markeredgecolor()), s[2]))
    return pairs, colours


def _explained_by_legend(style: tuple, pairs: set, colours: set) -> bool:
    """A line matches a handle of its colour and marker; a fill or collection one of its colour."""
    if style[0] == "line":
        return (style[1], style[2]) in pairs
    colour = style[2] if style[0] == "collection" else style[1]
    return colour in colours


def _is_reference_line(ax, artist) -> bool:
    """An unlabelled black or grey line across the axes (axhline / axvline at 0, a grid): no category."""
    if not isinstance(artist, Line2D) or not artist.get_label().startswith("_"):
        return False
    if artist.get_transform() == ax.transData:
        return False
    return _achromatic(artist.get_color())


def _achromatic(colour) -> bool:
    """Black, white or a grey."""
    r, g, b, _ = matplotlib.colors.to_rgba(colour)
    return max(r, g, b) - min(r, g, b) < 0.05


def _errorbar_lengths(container: ErrorbarContainer) -> np.ndarray:
    lengths = []
    for coll in container[2]:
        for seg in coll.get_segments():
            seg = np.asarray(seg, float)
            if len(seg) >= 2:
                lengths.append(float(np.hypot(*(seg[-1] - seg[0]))))
    return np.array(lengths)


def figure_problems(fig, require_title: bool = True) -> list[str]:
    """What a reader of ``fig`` would miss, one sentence each; empty when the figure reads.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure, drawn (its legends and colour bars made).
    require_title : bool
        Also ask for a title on every data axes or a figure title (off for a function that
        draws into a caller's axes).

    Returns
    -------
    list of str
        One entry per problem, naming the axes by its title or position.
    """
    problems: list[str] = []
    fig.canvas.draw()  # resolves categorical / fixed tick labels
    colorbars = [ax for ax in fig.axes if _is_colorbar(ax)]
    suptitle = fig._suptitle.get_text() if fig._suptitle is not None else ""
    for i, ax in enumerate(fig.axes):
        name = f"axes {i} ({ax.get_title() or 'untitled'})"
        if _is_colorbar(ax):
            if not (ax.get_ylabel().strip() or ax.get_xlabel().strip()):
                problems.append(f"{name}: colour bar without a label")
            continue
        artists = _data_artists(ax)
        if not artists and not ax.containers:
            continue
        dims = [("x", ax.xaxis, "get_xlabel"), ("y", ax.yaxis, "get_ylabel")]
        if hasattr(ax, "get_zlabel"):
            dims.append(("z", ax.zaxis, "get_zlabel"))
        for dim, axis, getter in dims:
            if not ax.axison or not axis.get_visible():
                continue
            label = _label_of(ax, getter).strip()
            if not label:
                problems.append(f"{name}: no {dim} label")
            elif not _is_categorical(axis) and not _has_unit(label):
                problems.append(f"{name}: {dim} label {label!r} gives no unit (brackets) nor says it is a count/index")
        twins = [o for o in fig.axes if np.allclose(o.get_position().bounds, ax.get_position().bounds)]
        if require_title and not (suptitle.strip() or any(o.get_title().strip() or o.get_title(loc="left").strip()
                                                          for o in twins)):
            problems.append(f"{name}: no title (neither the axes nor the figure says what is shown)")
        # styles drawn vs styles explained
        legend_texts = _legend_labels(fig)
        legend_pairs, legend_colours = _legend_keys(fig)
        in_errorbars = {id(part) for c in ax.containers if isinstance(c, ErrorbarContainer)
                        for part in (*c[1], *c[2])}
        container_label = {id(c[0]): c.get_label() for c in ax.containers
                           if isinstance(c, ErrorbarContainer) and c[0] is not None}
        styles: dict = {}
        for a in artists:
            if id(a) in in_errorbars or _is_reference_line(ax, a):
                continue
            s = _style(a)
            if s is None:
                continue
            styles.setdefault(s, []).append(a)
        text_colours = {to_hex(t.get_color()) for t in ax.texts if t.get_visible() and t.get_text().strip()}
        in_legend, in_text, unexplained = [], [], []
        for s, group in styles.items():
            named = any(container_label.get(id(a), a.get_label()) in legend_texts
                        and not container_label.get(id(a), a.get_label()).startswith("_") for a in group)
            colour = s[2] if s[0] == "collection" else s[1]
            if named or _explained_by_legend(s, legend_pairs, legend_colours):
                in_legend.append(s)
            elif colour in text_colours and not _achromatic(colour):
                in_text.append(s)  # a coloured note on the axes says what this colour marks
            else:
                unexplained.append((s, group))
        # one unexplained style is the data the axis labels describe; more than one, or one beside
        # styles the legend explains, leaves the reader guessing
        if len(unexplained) > 1 or (unexplained and in_legend):
            for s, group in unexplained:
                problems.append(f"{name}: {len(group)} artist(s) drawn as {s} have no legend entry")
        for a in artists:
            lab = a.get_label()
            if lab and not lab.startswith("_") and legend_texts and lab not in legend_texts:
                problems.append(f"{name}: artist labelled {lab!r} is missing from the legend")
        # colour-mapped artists need a colour bar
        mapped = [a for a in artists if getattr(a, "get_array", lambda: None)() is not None
                  and not isinstance(a, Patch)]
        if mapped and not colorbars:
            problems.append(f"{name}: colour-mapped data without a colour bar")
        for c in ax.containers:
            if isinstance(c, ErrorbarContainer) and c[2]:
                lengths = _errorbar_lengths(c)
                if lengths.size and np.all(lengths == 0):
                    problems.append(f"{name}: error bars {c.get_label()!r} all have zero length")
    return problems


def assert_readable_figure(fig, require_title: bool = True) -> None:
    """Raise AssertionError listing :func:`figure_problems` of ``fig`` when there are any."""
    problems = figure_problems(fig, require_title=require_title)
    assert not problems, "figure is not readable without its code:\n  " + "\n  ".join(problems)


def _check_all(figs: Iterable) -> None:
    for fig in figs:
        try:
            assert_readable_figure(fig)
        finally:
            plt.close(fig)


@pytest.fixture
def saved_figures(monkeypatch):
    """Every figure a call saves, with its file name: ``[(name, Figure), ...]`` (the files are still written)."""
    from matplotlib.figure import Figure

    seen: list = []
    original = Figure.savefig

    def savefig(self, fname, *args, **kwargs):
        seen.append((str(getattr(fname, "name", fname)), self))
        return original(self, fname, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return seen


def _check_saved(saved: list, expected: Iterable[str]) -> None:
    """Every expected file was saved, and every saved figure reads (all problems listed at once)."""
    from pathlib import Path

    names = {Path(n).name for n, _ in saved}
    missing = set(expected) - names
    assert not missing, f"figures not written: {sorted(missing)}"
    report = []
    for name, fig in saved:
        report += [f"{Path(name).name}: {p}" for p in figure_problems(fig)]
        plt.close(fig)
    assert not report, "figures not readable without their code:\n  " + "\n  ".join(report)


# --------------------------------------------------------------- the checker can fail
def _good_figure():
    fig, ax = plt.subplots()
    ax.plot([0, 1, 2], [0, 1, 4], "o-", label="measured")
    ax.plot([0, 1, 2], [0, 1, 2], "s--", label="model")
    ax.errorbar([0, 1, 2], [1, 2, 3], yerr=[0.1, 0.2, 0.1], fmt="^", label="with spread")
    ax.axhline(0.0, color="k", lw=0.5)  # a reference line needs no entry
    ax.set(xlabel="time (s)", ylabel="distance (m)", title="A readable figure")
    ax.legend()
    return fig


def test_a_readable_figure_passes():
    fig = _good_figure()
    assert figure_problems(fig) == []
    plt.close(fig)


@pytest.mark.parametrize("spoil, expected", [
    (lambda fig, ax: ax.set_xlabel(""), "no x label"),
    (lambda fig, ax: ax.set_ylabel("distance"), "gives no unit"),
    (lambda fig, ax: ax.set_title(""), "no title"),
    (lambda fig, ax: ax.plot([0, 2], [3, 3], "kx"), "have no legend entry"),
    (lambda fig, ax: ax.plot([0, 2], [3, 1], color="tab:purple", label="forgotten"), "missing from the legend"),
    (lambda fig, ax: ax.errorbar([0, 1], [1, 2], yerr=[0.0, 0.0], fmt="o", color="tab:red", label="sd of one seed"),
     "zero length"),
    (lambda fig, ax: fig.colorbar(ax.imshow(np.eye(3), extent=(0, 2, 0, 4))), "colour bar without a label"),
    (lambda fig, ax: ax.scatter([0, 1], [1, 2], c=[0.0, 1.0]), "without a colour bar"),
], ids=["x-label", "unit", "title", "marker", "label", "zero-error-bar", "colour-bar", "colour-map"])
def test_the_checker_fails_a_figure_a_reader_cannot_read(spoil, expected):
    fig = _good_figure()
    ax = fig.axes[0]
    spoil(fig, ax)  # (a labelled artist added after the legend was made is not in it)
    with pytest.raises(AssertionError, match=expected):
        assert_readable_figure(fig)
    plt.close(fig)


def test_the_one_seed_bar_chart_of_issue_21_fails():
    """The Ch.3 performance bars before issue 21: one seed, 'sd over repetitions' bars of zero length."""
    fig, ax = plt.subplots()
    ax.bar([0, 1], [0.4, 0.5], yerr=[0.0, 0.0], capsize=3, label="open loop")
    ax.set(xlabel="strategy index", ylabel="ARR (rate)", title="ARR, sd over repetitions")
    ax.legend()
    with pytest.raises(AssertionError, match="zero length"):
        assert_readable_figure(fig)
    plt.close(fig)


def test_shared_x_axis_label_and_twin_axes_title_count():
    fig, (a, b) = plt.subplots(2, 1, sharex=True)
    a.plot([0, 1], [0, 1])
    b.plot([0, 1], [1, 0])
    a.set(ylabel="speed (m/s)", title="top")
    b.set(xlabel="time (s)", ylabel="count", title="bottom")
    twin = b.twinx()
    twin.plot([0, 1], [3, 4], color="tab:green", label="angle")
    twin.set_ylabel("angle (deg)")
    assert figure_problems(fig) == []
    plt.close(fig)


# --------------------------------------------------------------- library plot functions (fast)
def test_experiment_sweep_figures_read():
    from cansim.experiments import bump, diffusion, integration_gain, lv_interference, reanchoring

    cases = {
        bump: [bump.run({"exc_sigma_cells": s, "global_inhibition": g, "duration_steps": 20}, 0)
               for s in (0.5, 1.0) for g in (2e-5, 0.5)],
        diffusion: [diffusion.run({"noise_std_cells": s, "n_trials": 3, "duration_steps": 20}, 0) for s in (0.2, 0.5)]
        + [diffusion.run({"noise_kind": "injection", "noise_energy": e, "n_trials": 3, "duration_steps": 20}, 0)
           for e in (0.001, 0.003)],
        integration_gain: [integration_gain.run({"speed_cells_per_step": v, "dynamics": d, "duration_steps": 12}, 0)
                           for v in (0.0, 0.5) for d in (False, True)],
        reanchoring: [reanchoring.run({"injection_energy": e, "offset_cells": o, "duration_steps": 40}, 0)
                      for e in (0.1, 0.3) for o in (5.0, 30.0)],
        lv_interference: [lv_interference.run({"n_views": k, "trace_decay": 0.5, "recall_steps": 10}, 0) for k in (2, 4)],
    }
    assert any(r["collapsed"] for r in cases[bump])  # the crosses are drawn, so their legend entry is checked
    assert any(r["mode"] == "jump" for r in cases[reanchoring])  # likewise the jump triangles
    _check_all(module.figure(results) for module, results in cases.items())


def _square_map():
    import math

    from maps.experience_map import ExperienceMap, MapConfig
    from maps.se2 import SE2Geometry

    em = ExperienceMap(MapConfig(relax_passes=1, relax_budget=None), SE2Geometry(initial_heading_deg=0.0))
    em.update((0, 0, 0), 0, 0)
    em.on_odo(1.0, 0.0, 1.0)
    em.update((5, 0, 0), 1, 0)
    em.on_odo(1.0, math.pi / 2, 1.0)
    em.update((5, 5, 0), 2, 1)
    em.on_odo(0.0, math.pi / 2, 1.0)
    em.on_odo(1.2, 0.0, 1.0)
    em.update((0, 5, 0), 3, 2)
    return em


def test_map_figures_read(tmp_path, saved_figures):
    from types import SimpleNamespace

    from cansim.tools.bag_replay import ReplayResult, write_outputs
    from maps.plot_maps import plot_experience_ids, plot_experience_map

    em = _square_map()
    truth = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float)
    figs = [plot_experience_map(em, truth, truth + 0.05, [0, 1, 2, 3, 0]), plot_experience_map(em),
            plot_experience_ids([0, 1, 2, 3, 0, 1, 2, 4], relocalisation_indices=[4, 5, 7], base_end=4,
                                correct_indices=[4], kidnap_indices=[6])]
    _check_all(figs)
    # the bag replay's map figure (cansim replay)
    result = ReplayResult(slam=SimpleNamespace(experience_map=em), stamp_ns=np.arange(4, dtype=np.int64) * 10**8,
                          exp_ids=np.array([0, 1, 2, 3]), topics=None, n_odometry=4, n_images=4)
    write_outputs(result, tmp_path)
    _check_saved(saved_figures, ["experience_map.png"])


def test_whisker_io_figures_read():
    from whisker_io.array.geometry import WhiskerArray
    from whisker_io.contact.detection import detect_contact
    from whisker_io.features.pfh import point_feature_histogram
    from whisker_io.features.sda import SlopeDistribution
    from whisker_io.plots.scene import plot_pfh, plot_scene, plot_tactile_image
    from whisker_io.plots.signals import plot_sda, plot_whisk, plot_xy_gradient
    from whisker_io.records.whisk_record import WhiskRecord
    from whisker_io.sim.objects import make_object
    from whisker_io.sim.sweep import sweep_array

    arr = WhiskerArray.thesis()
    pose = np.eye(4)
    pose[1, 3], pose[2, 3] = -0.1 - 0.2019 - 0.01, 0.175  # nose 1 cm in front of the box's -y face
    contacts = sweep_array(arr, make_object("box"), pose)
    assert any(c is None for c in contacts) and any(c is not None for c in contacts)  # both whisker kinds drawn
    k = np.arange(2400, dtype=float)
    y = (np.clip(k - 599, 0, 400) - np.clip(k - 1299, 0, 400)) * 5.0 + np.random.default_rng(0).normal(0, 4.0, k.size)
    rec = WhiskRecord("A1", -0.8 + 1.6 * k / k.size, 0.3 * y, y)
    contact = detect_contact(rec)
    assert contact is not None
    modules = tuple(f"A{i}" for i in range(6))
    sda = SlopeDistribution(np.array([0.5, -0.3, 0, 1.0, 0.2, 0]), np.array([1, 1, 0, 1, 1, 0], bool), modules)
    ref = SlopeDistribution(np.array([0.4, -0.2, 0.1, 0.9, 0, 0]), np.array([1, 1, 1, 1, 0, 0], bool), modules)
    hist = point_feature_histogram(np.random.default_rng(0).uniform(-0.1, 0.1, (18, 3)) + [0, 0.3, 0]).histogram
    _check_all([plot_scene(make_object("box"), arr, pose, contacts), plot_pfh(hist),
                plot_tactile_image(np.arange(18, dtype=np.uint8).reshape(3, 6) * 10),
                plot_whisk(rec, contact), plot_xy_gradient(rec, contact), plot_sda(sda, ref), plot_sda(sda)])


def test_radial_figures_read():
    from whisker_io.radial.evaluation import PCAResult
    from whisker_io.radial.plots import plot_boxplots, plot_histograms, plot_pca_loadings

    rng = np.random.default_rng(0)
    pca = PCAResult(("CP", "CA", "DV", "DA", "AV", "AA", "WL"), np.eye(3, 7), np.array([0.5, 0.3, 0.2]))
    errors = {"svr9": rng.normal(0, 0.1, 60), "poly5": np.r_[rng.normal(0, 0.2, 60), [-5.0, 9.0]]}  # outliers: the triangles
    _check_all([plot_pca_loadings(pca), plot_histograms(errors, "radial error / whisker length (Eq 4.1)",
                                                        value_range=(-0.5, 0.5), title="radial error per model"),
                plot_boxplots({k: np.abs(v) * 100 for k, v in errors.items()}, "|radial error| (% of whisker length)",
                              title="Evans-style split")])


def test_boxplot_handles_name_every_mark():
    from whisker_io.plots.axes import boxplot_handles

    fig, ax = plt.subplots()
    parts = ax.boxplot([np.r_[np.arange(10.0), 40.0]], notch=True)  # 40 is an outlier
    labels = [h.get_label() for h in boxplot_handles(parts)]
    assert labels == ["median (notch: ~95 % CI of the median)", "box: quartiles; whiskers: data within 1.5 IQR",
                      "outlier (beyond the whiskers)"]
    assert boxplot_handles({"boxes": []}) == []
    plt.close(fig)


@settings(max_examples=10, deadline=None)
@given(groups=st.lists(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=30), min_size=1, max_size=4),
       notch=st.booleans(), fliers=st.booleans())
def test_boxplot_handles_match_what_was_drawn(groups, notch, fliers):
    """Median and box always; the notch named only when drawn; an outlier entry iff an outlier is drawn."""
    from whisker_io.plots.axes import boxplot_handles

    fig, ax = plt.subplots()
    try:
        parts = ax.boxplot([np.asarray(g) for g in groups], notch=notch, showfliers=fliers)
        labels = [h.get_label() for h in boxplot_handles(parts)]
        drawn_outlier = any(len(f.get_xdata()) for f in parts["fliers"])
        assert labels[0].startswith("median") and ("notch" in labels[0]) == notch
        assert labels[1].startswith("box: quartiles")
        assert ("outlier (beyond the whiskers)" in labels) == drawn_outlier
        ax.legend(handles=boxplot_handles(parts))
        ax.set(xlabel="group index", ylabel="value (m)", title="box plot")
        assert_readable_figure(fig)
    finally:
        plt.close(fig)


def _load_example(name: str):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_example_figures_read(tmp_path, saved_figures):
    ring = _load_example("ring_attractor")
    ring.plot(ring.run(steps=200, seed=0), tmp_path / "ring_attractor.png")
    spiking = _load_example("spiking_ring")  # its plot only, on a made-up run (the run itself is the spiking helper's)
    t = np.linspace(0.0, 2.0, 41)
    heading = np.degrees(t) % 360
    spiking.plot({"time_s": t, "true_deg": heading, "rate_deg": heading + 1, "spiking_deg": heading - 1,
                  "spike_time_s": np.repeat(t, 3), "spike_cell": np.tile([10, 11, 12], t.size),
                  "metrics": {"rms_vs_true_deg": 1.0, "rms_vs_rate_deg": 2.0}}, tmp_path / "spiking_ring.png")
    _check_saved(saved_figures, ["ring_attractor.png", "spiking_ring.png"])


def test_whisker_ratslam_demo_figures_read(tmp_path, saved_figures):
    from cansim.studies import whisker_ratslam_demo

    result = whisker_ratslam_demo.run("mug", loops=1, seed=0, progress=False)
    whisker_ratslam_demo.figures(result, tmp_path)
    _check_saved(saved_figures, ["whisker_ratslam_map.png", "whisker_ratslam_experiences.png"])


def test_ratslam_demo_figures_read(tmp_path, saved_figures):
    from cansim.studies import ratslam_demo

    assert ratslam_demo.main(["--out", str(tmp_path)]) == 0
    _check_saved(saved_figures, ["ratslam_map.png", "ratslam_experience_ids.png", "ratslam_experience_ids_kidnapped.png"])


def test_rat_trajectory_figures_read(tmp_path, saved_figures):
    """The rat study's two figures (60 s of Sargolini, rate models only: ~3 s)."""
    pytest.importorskip("ratinabox", reason="ratinabox (extra 'rat') is not installed")
    from cansim.studies import rat_trajectories

    assert rat_trajectories.main(["--quick", "--duration-s", "60", "--no-spiking", "--out", str(tmp_path)]) == 0
    _check_saved(saved_figures, ["rat_trajectories_paths.png", "rat_trajectories_errors.png"])


# --------------------------------------------------------------- whole quick studies (slow)
@pytest.mark.slow
@pytest.mark.parametrize("study, argv, expected", [
    ("ch3_maze", ["--quick"], ["ch3_map.png", "ch3_experience_ids.png", "ch3_performance.png", "ch3_distances.png"]),
    ("ch4_radial_distance", ["--quick"], ["fig4_6_pca_loadings.png", "fig4_8_mesh_distance.png", "fig4_9_radial_error.png",
                                          "fig4_10_evans.png", "fig4_11_length_generalisation.png"]),
    ("ch5_object_maps", ["--quick"], ["fig5_14b_dead_reckoning.png", "fig5_15_localisation.png", "fig5_16_history.png",
                                      "fig5_17_confidence.png"]),
    ("ch6_active_exploration", ["--quick"], ["fig6_2_spc_poses.png", "fig6_4_rc_ic.png", "fig6_6_confidence_spc.png",
                                             "fig6_7_im_threshold.png", "fig6_8_im_strategy.png", "fig6_9_srt_strategy.png"]),
    ("recognition", ["--quick"], ["recognition_confusion.png", "recognition_accuracy_vs_distance.png",
                                  "recognition_accuracy_vs_library.png"]),
])
def test_quick_study_figures_read(study, argv, expected, tmp_path, saved_figures):
    import importlib

    module = importlib.import_module(f"cansim.studies.{study}")
    assert module.main([*argv, "--out", str(tmp_path)]) in (0, None)
    _check_saved(saved_figures, expected)
