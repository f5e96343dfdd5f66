"""The recognition benchmark (cansim.studies.recognition; issue 22 item 4) in the quick mode a user runs.

One run of ``cansim study recognition --quick`` (12-object library, seed 0, presentations
along trajectory A, trajectory B and viewpoints 5-10 cm / 5-15 deg from the mapping
poses, three novel objects; both matchers): the outputs, what holds today (the own map
leads along the mapping path for both matchers; the thesis matcher decides nothing for
novel objects and nothing wrong; the surface matcher names more objects from new paths),
and the issue's headline target, which neither matcher reaches (strict xfail: it turns
into a failure the day it is reached, so the marker is removed then).
"""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from cansim.studies import recognition

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    from entry_point import run_cansim

    out = tmp_path_factory.mktemp("recognition")  # through the installed entry point, as a user runs it
    done = run_cansim("study", "recognition", "--quick", "--out", str(out), "--no-progress")
    assert done.returncode == 0, done.stderr[-3000:]
    with open(out / "recognition_runs.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return out, rows


def test_outputs_and_columns(quick):
    out, rows = quick
    assert tuple(rows[0]) == recognition.COLUMNS
    library = [r for r in rows if r["novel"] == "False"]
    novel = [r for r in rows if r["novel"] == "True"]
    assert len({r["presented"] for r in library}) == 12 and len({r["presented"] for r in novel}) == 3
    assert {(r["presentation"], r["distance_bin"]) for r in rows} == {("A", ""), ("B", ""), ("viewpoints", "vp 5-10 cm")}
    assert len(rows) == (12 + 3) * 3 * len(recognition.DEFAULT_MATCHERS)
    assert {r["matcher"] for r in rows} == set(recognition.DEFAULT_MATCHERS) == {"thesis", "surface"}
    for name in ("recognition_confusion.png", "recognition_accuracy_vs_distance.png",
                 "recognition_accuracy_vs_library.png", "recognition_confusion_surface.png", "recognition_unmapped.png",
                 "recognition_unmapped_surface.png"):
        assert (out / name).stat().st_size > 10_000
    text = (out / "recognition_summary.txt").read_text()
    assert "trajectory B" in text and "Fig 5.17" in text
    assert "Targets (issue 22's acceptance" in text and "(a library object named as another; novel ones" in text
    # what the maps never felt: a share for every library presentation, blank for novel objects; none along A's own
    # path is near the share from the viewpoints (the mapping path felt where A goes)
    assert all(r["unmapped_contact_fraction"] == "" for r in novel)
    share = {(r["presented"], r["presentation"]): float(r["unmapped_contact_fraction"]) for r in library}
    assert all(0.0 <= v <= 1.0 for v in share.values())
    along_a = np.median([v for (n, p), v in share.items() if p == "A"])
    from_vp = np.median([v for (n, p), v in share.items() if p == "viewpoints"])
    assert along_a < from_vp, (along_a, from_vp)
    assert "own map felt nothing" in text
    surfaces = sorted((out / "maps" / "seed0").glob("*_surface.npz"))  # the stored surfaces of the surface matcher
    assert len(surfaces) == 12
    for f in surfaces:
        with np.load(f) as z:
            assert z["points_m"].shape[1] == 3 and len(z["points_m"]) >= 20 and np.isfinite(z["points_m"]).all()
            assert z["viewpoints_m"].shape == z["points_m"].shape and np.isfinite(z["viewpoints_m"]).all()


def test_viewpoints_lie_in_their_bin(quick):
    _, rows = quick
    vp = [r for r in rows if r["presentation"] == "viewpoints"]
    assert all(0.05 <= float(r["median_distance_m"]) <= 0.10 for r in vp)
    assert all(5.0 <= float(r["median_rotation_deg"]) <= 20.0 for r in vp)  # the turn, seen from the nearest pose
    along_a = [r for r in rows if r["presentation"] == "A"]
    assert all(float(r["median_distance_m"]) < 1e-9 for r in along_a)  # A retraces the mapping poses


def test_along_the_mapping_path_the_own_map_leads(quick):
    """Along A (the mapping poses) no run decides for another object, and the own map ends ahead
    in every run, for both matchers (issue 22: "along A ... own map first in every run").
    Measured before the poses reached for 3 whiskers (``REACH_CONTACTS``): the surface matcher
    led in 11 of 12 - the Blob's filter, its first whisks fitted better by the Kettle, was
    pruned - and the duck, felt by 3 whiskers in 17 % of its whisks, was named by neither."""
    _, rows = quick
    behind = {"thesis": [], "surface": []}
    for r in rows:
        if r["presentation"] == "A" and r["novel"] == "False":
            assert r["decision"] in ("", r["presented"]), (r["matcher"], r["presented"])
            if float(r["final_ic_own"]) <= float(r["final_ic_best_other"]):
                behind[r["matcher"]].append(r["presented"])
    assert behind == {"thesis": [], "surface": []}, behind


def test_thesis_matcher_decides_nothing_for_novel_objects_and_nothing_wrong(quick):
    _, rows = quick
    rows = [r for r in rows if r["matcher"] == "thesis"]
    novel = [r for r in rows if r["novel"] == "True"]
    assert sum(r["decision"] == "" for r in novel) >= math.ceil(0.95 * len(novel))
    library = [r for r in rows if r["novel"] == "False"]
    assert sum(r["decision"] not in ("", r["presented"]) for r in library) <= 0.05 * len(library)


def test_surface_matcher_names_more_objects_from_new_paths(quick):
    """Under the thesis' odometry noise the surface matcher names 16 of 24 along B and the
    viewpoints (15 at the fixed standoff, 12 with the blind proposal) where the region match
    names none (it also decides wrongly, 1 of 36 runs: the module's Status)."""
    _, rows = quick
    new_path = [r for r in rows if r["presentation"] in ("B", "viewpoints") and r["novel"] == "False"]
    correct = {m: sum(r["decision"] == r["presented"] for r in new_path if r["matcher"] == m) for m in ("thesis", "surface")}
    assert correct["surface"] >= correct["thesis"] + 6, correct


@pytest.mark.xfail(strict=True, reason="issue 22 open: the thesis' Eq 5.5 region match recognises visited poses, not "
                                       "the surface (along B 0/12); the surface matcher on interpolated surfaces names 8/12 "
                                       "along B and 7/12 from the viewpoints under the thesis' odometry noise, with wrong "
                                       "decisions (distorted maps); at a quarter of that noise, with the matcher and the maps' "
                                       "pose graphs told so, 36/36 along B and 33-35/36 from the viewpoints on seeds 0-2, "
                                       "3-5 and 6-8 (README), but this quick run is the thesis' noise")
@pytest.mark.parametrize("presentation", ["B", "viewpoints"])
def test_headline_identified_from_a_new_path(quick, presentation):
    """Held by either matcher: 90 % correct decisions."""
    _, rows = quick
    share = {}
    for m in recognition.DEFAULT_MATCHERS:
        runs = [r for r in rows if r["matcher"] == m and r["presentation"] == presentation and r["novel"] == "False"]
        share[m] = sum(r["decision"] == r["presented"] for r in runs) / len(runs)
    assert max(share.values()) >= 0.9, share


def test_the_surface_matcher_identifies_along_b_when_the_maps_are_accurate_enough(tmp_path):
    """With a quarter of the Eq 6.4-6.11 odometry noise (stored surfaces 3-9 mm from the mesh) the
    particle filters on the interpolated surfaces name Mug, Bear and Barrel along trajectory B at
    IC 300 with no impulse to another object (215-227 own each), where the thesis' region match
    names two with 50-53 wrong impulses each; the Kettle, whose B contacts fit the Mug's surface,
    is named too with the registration-refined proposal (192 own, 4 wrong impulses; the blind
    proposal took it for the Mug, 15 own and 180 wrong); the novel knot gets no decision."""
    rows = recognition.run(tmp_path / "out", objects=["mug", "bear", "barrel", "kettle"], novel=["knot-h0"], bins=(),
                           seeds=(0,), matchers=("thesis", "surface"), odometry_scale=0.25, progress=False)
    along_b = {(r["matcher"], r["presented"]): r for r in rows if r["presentation"] == "B"}
    surface = [along_b["surface", n] for n in ("mug", "bear", "barrel", "kettle")]
    thesis = [along_b["thesis", n] for n in ("mug", "bear", "barrel", "kettle")]
    assert sum(r["correct"] for r in surface) >= 3
    assert sum(r["correct"] for r in surface) > sum(r["correct"] for r in thesis)
    for r in surface:
        if r["correct"]:
            assert r["impulses_other"] <= 0.05 * r["impulses_own"], r["presented"]
    assert sum(r["impulses_own"] for r in surface) >= 2 * sum(r["impulses_own"] for r in thesis)
    assert sum(r["decision"] not in ("", r["presented"]) for r in surface) <= 1
    assert along_b["surface", "knot-h0"]["decision"] == ""


def test_run_takes_the_mesh_options_and_the_summary_says_when_runs_are_too_short(tmp_path):
    """run() had no scale_to_m / up_axis although its error told the user to pass scale_to_m; and 40 whisks, too
    few for any decision at IC 300, were reported only as targets not held."""
    import trimesh

    trimesh.creation.capsule(height=200.0, radius=50.0).export(tmp_path / "capsule_mm.stl")  # 300 mm, z up
    rows = recognition.run(tmp_path / "out", objects=[str(tmp_path / "capsule_mm.stl"), "mug"], novel=["box"],
                           seeds=(0,), bins=(), whisks=40, workers=1, progress=False, matchers=("thesis",),
                           scale_to_m=0.3)
    copy = tmp_path / "out" / "objects" / "capsule_mm.ply"
    assert copy.exists() and {(r["presented"], r["mesh_file"]) for r in rows} == {("capsule_mm", str(copy)), ("mug", ""),
                                                                                   ("box", "")}
    assert {r["decision"] for r in rows} <= {"", "capsule_mm", "mug"}  # by label, as the summary names them
    assert (tmp_path / "out" / "maps" / "seed0" / "capsule_mm.npz").exists()  # the map file by the same name
    text = recognition.summary(rows, 1.0, False)
    short = sum(int(r["whisks"]) < recognition.whisks_to_decide() for r in rows)  # whole loops: some reach it
    assert short > 0 and f"{short} of {len(rows)} runs had fewer whisks than any decision at IC 300 needs" in text


def test_reach_contacts_0_maps_and_presents_at_the_fixed_standoff(monkeypatch) -> None:
    """--reach-contacts 0 is the fixed standoff for every object, the maps' poses as the presentations': the
    Ch.5 study's reaching for shapes its standoff misses (choose_reach) is not applied to the maps, even for
    a torus lying flat that the standoff never touches with 3 whiskers."""
    from cansim.studies import ch5_object_maps as ch5
    from cansim.studies import recognition as rec
    from whisker_io.sim import trajectories as ch5_trajectories
    from whisker_io.sim.catalogue import resolve_object

    setup = rec.Setup(seed=0, map_loops=1, whisks=10, thresholds=(0.9, 0.3), out=".", reach_contacts=0,
                      rolls_deg=(("torus_flat", 0.0),))
    torus = resolve_object("torus_flat").mesh
    mapped = ch5.trajectory_choice(torus, rec._settings(setup), *ch5.STEP, setup.roll_of("torus_flat"))
    assert mapped == (0, 0.0)  # the fixed standoff at the object's roll, for map_job and present_job alike
    # present_job whisks through the same rule: its loop A is the fixed-standoff loop at that roll
    calls = []

    def spy(mesh, family="A", n_loops=2, **kw):
        calls.append((family, kw.get("reach_contacts"), kw.get("roll_deg")))
        raise _Stop

    monkeypatch.setattr(ch5_trajectories, "object_trajectory", spy)
    with pytest.raises(_Stop):
        rec.present_job(("torus_flat", False, "A", None, [], [], setup, None))
    assert calls == [("A", 0, 0.0)]


class _Stop(Exception):
    """Raised by a spy to stop a job once it has said what it would whisk."""


def test_at_a_quarter_of_the_odometry_noise_the_headline_holds(tmp_path_factory):
    """The quick settings with the arm's odometry a quarter of Eq 6.4-6.11's (``--odometry-noise 0.25``; the matcher's
    motion model and the maps' pose graphs told so): the issue's targets along A, B and the 5-10 cm viewpoints and
    for wrong decisions hold on seed 0 (and on seeds 1-5: the README's table). The novel objects' do not (the
    bucket is named the barrel), so they are not asserted here."""
    out = tmp_path_factory.mktemp("rec_quarter")
    rows = recognition.run(out, seeds=(0,), bins=("vp 5-10 cm",), matchers=("surface",), odometry_scale=0.25,
                           progress=False)
    library = [r for r in rows if not r["novel"]]
    right = {p: sum(r["decision"] == r["presented"] for r in library if r["presentation"] == p) for p in ("A", "B", "viewpoints")}
    total = {p: sum(r["presentation"] == p for r in library) for p in right}
    assert right["A"] == total["A"] == 12, right
    assert right["B"] >= 0.9 * total["B"] and right["viewpoints"] >= 0.9 * total["viewpoints"], right
    assert sum(r["decision"] not in ("", r["presented"]) for r in library) <= 0.05 * len(library)
