"""Recognition benchmark: identify an object from a path it was not mapped on (issue 22).

The thesis identifies an object by the re-localisations of an exploration into the
object maps of a library (Sec 5.2.2.2, Fig 5.16-5.17): each re-localisation into object
``k``'s map is an impulse into ``k``'s leaky integrator, and the first object whose
integrated confidence reaches 300 (Sec 6.2) is the decision. This study measures how
well that works when the presentation does not retrace the mapping path.

What runs
---------
* **Library** (:func:`whisker_io.sim.shapes.library_names`): the project's eight thesis
  objects plus procedural shapes that do not fill their bounding box (superquadrics,
  star-convex blobs, tori, hollow and handled shapes), 12 objects by default and 25 / 50
  for the library-size figure; novel objects (:func:`whisker_io.sim.shapes.novel_names`,
  families never in a library) are presented but not mapped. ``--objects`` takes any
  names or mesh files instead (:func:`whisker_io.sim.catalogue.resolve_object`).
* **Maps**: every library object is mapped along ``--map-loops`` loops of trajectory A
  (:func:`whisker_io.sim.trajectories.object_trajectory`) by WhiskerRatSLAM with the
  mapping preset (tip contacts at 0.3 of the Sec 6.1.3.1.2 contact noise, Eq 6.4-6.11
  odometry noise, T_pfh / T_sda calibrated on the Mug as the Ch.5 study does, on the run's
  first seed unless ``--calibration pooled``: Status).
* **Poses that reach the surface**: every mapping and presentation pose whose whisk would
  touch with fewer than :data:`REACH_CONTACTS` (3) whiskers moves forward along its own
  axis until 3 touch (``--reach-contacts``; 0 gives the fixed standoff of the Ch.5 study;
  :func:`whisker_io.sim.trajectories.object_trajectory`, its module docstring item 6). The
  thesis array leaves the space straight ahead of its front bases unswept, so at the fixed
  standoff narrow parts went untouched: the duck along A was felt by 3 whiskers or more in
  17 % of its whisks, and the study's presentations gave region observations in 70 % of
  their whisks (86 % reaching; Status).
* **A roll per object**: the array is rolled about its axis by the thesis' 90 deg on every
  trajectory of an object, unless a reaching loop of its trajectory A is touched by 3 whiskers
  more than 10 % of its poses more often at 0 deg
  (:func:`whisker_io.sim.trajectories.reaching_roll_deg`; ``--roll-deg DEG`` sets one roll for
  all; the CSV's ``roll_deg`` column). Of the 50-object library the four flat tori, two bowls
  and one duck variant take 0 deg (at 90 deg they lie between the array's rows: 0-21 % of
  their poses touched by 3 whiskers); the 12-object library and the three novel shapes keep
  90 deg, so the quick run is unchanged. Seed 0, all 50 objects and the 3 novel ones presented
  along B against the 50-object library (surface matcher, IC 300; offline, the study's
  functions): correct 12 -> 13 of 50 (``torus_flat-v0`` named), wrong 6 -> 7 (``bowl-v2`` taken
  for the upright torus), novel undecided 3 -> 3 of 3; matcher cost 1.39 -> 1.26 ms a whisk
  (2 threads), presentations over 2 ms 11 -> 8 of 53 (the flat tori were the slowest: nothing
  fitted them).
* **One step for every object**: maps and presentations step at most 0.11 m / 12 deg
  between whisks (:data:`cansim.studies.ch5_object_maps.STEP`, the thesis' step, Sec 5.2.2.1), the Box included (the Ch.5
  study maps the Box at 3 cm / 8 deg to localise on its flat faces). Maps of different
  density bias any matcher that compares surfaces: with the Box mapped at 3 cm (1,400
  stored contacts against 110-580 for the others) its surface fitted the contacts of most
  other objects better than their own maps did under the thesis' odometry noise (surface
  matcher along B with its tolerance lifted: Mug, Jug and Kettle all taken for the Box; with
  the Box left out of the library Mug, Kettle and Bear got 179-226 own impulses against
  0-11 wrong).
* **Presentations**: each library object and each novel object is explored from scratch
  against the appended library (:meth:`cansim.models.whisker_ratslam.WhiskerRatSLAM.library`)
  along trajectory A (the mapping path), along trajectory B (another loop family), and
  along viewpoint sets: every mapping pose moved tangentially (about the object's
  centre) and turned about a random axis so that its distance to the *nearest* mapping
  pose lies in a bin (``VIEWPOINT_BINS``; the issue's 5-10 cm / 5-15 deg among them);
  each run is at least ``--whisks`` whisks long (whole loops).
* **Matchers** (``--matchers``, default both; every matcher decides the same
  whisks): ``thesis``, the Eq 5.5 region match of the appended library (as Ch.5 runs
  it); ``surface``, :class:`maps.surface_match.SurfaceMatcher` registering each whisk's
  contacts to every library object's stored surface (what the mapping run felt, placed
  by its whisk poses optimised as a pose graph, :func:`maps.pose_graph.whisk_surface`;
  written next to each map as ``<object>_surface.npz``), started at the presentation's
  first pose; its impulses go into the same leaky integrators (:mod:`maps.recognition`).

Outputs (``--out``)
-------------------
* ``recognition_runs.csv`` - written whole once every seed has run (an interrupted run, Ctrl-C,
  keeps its finished seeds' runs in ``recognition_runs_interrupted.csv``, :data:`INTERRUPTED_CSV`,
  with the same columns) - one row per run (columns :data:`COLUMNS`; among them
  ``whisks_with_contact``, the whisks that observed a region - 3 contacts or more, Eq 5.5 -,
  and, with the surface matcher, ``unmapped_contact_fraction``, the share of the
  presentation's contacts where the presented object's map felt nothing,
  :func:`unmapped_contact_fraction`; ``presented`` and ``decision`` name objects by their
  labels, :func:`whisker_io.sim.catalogue.object_labels` - the names of the summary, the figures
  and the map files ``maps/seed<N>/<label>.npz`` -, and ``mesh_file`` is the mesh file the run
  loaded for the presented object, empty for a named one: a file changed by ``--scale-to-m`` /
  ``--up-axis`` is its copy in ``objects/``);
* ``recognition_confusion.png`` - decisions per presented object (rows) and decided
  identity (columns, plus a last column "(no decision)", :data:`NO_DECISION`), per presentation;
* ``recognition_accuracy_vs_distance.png`` - correct decisions vs viewpoint distance;
* ``recognition_accuracy_vs_library.png`` - correct decisions vs library size
  (full mode: 12, 25, 50 objects);
* ``recognition_unmapped.png`` (with the surface matcher) - per presentation of a library object, the share of its
  contacts where the own map felt nothing against the own object's impulses, correct and
  missed runs marked;
* ``recognition_summary.txt`` - the issue's acceptance figures, each held or not, and
  the thesis' Fig 5.17 findings against the measured ones.

Run::

    cansim study recognition --quick        # 12 objects, 1 seed, A / B / 5-10 cm
    cansim study recognition                # 12 objects, 3 seeds, all bins; 25 and 50 objects
    cansim study recognition --quick --seed 3 --seeds 3 --matcher surface   # seeds 3-5, one matcher

Status (measured, see the summary of a run): with the thesis matcher a presentation
along the mapping path is identified, along trajectory B or a viewpoint set 5-10 cm away
it is not - the region features of Eq 5.5 match the poses visited, not the surface. The
``surface`` matcher (a particle filter per library object on the stored surfaces,
interpolated between the contacts; :mod:`maps.surface_match`, :mod:`maps.surface_field`)
identifies from new paths when the stored surfaces are accurate, and the surfaces are as
accurate as the odometry lets the maps be.

* **The odometry noise decides the headline** (2026-12-06; surface matcher, quick settings,
  seeds 0-2 by ``--quick --seeds 3 --matchers surface --odometry-noise S`` - the matcher was
  tuned on seed 0 - and held-out seeds 3-5 by ``run(out, seeds=(3, 4, 5), bins=("vp 5-10
  cm",), matchers=("surface",), odometry_scale=S)`` (seeds 6-8 likewise, run once on 2026-12-06
  after every choice was made); correct along A / B / viewpoints 5-10 cm of 36, wrong of 108,
  novel undecided of 27):

  ===== ========= ============= ============= ============== =====================
  S     seeds     A / B / vp    wrong         novel          bucket taken for barrel
  ===== ========= ============= ============= ============== =====================
  1     0-2       36 / 24 / 17  10            18             (the default)
  1     3-5       36 / 19 / 11  28            14
  0.5   0-2       36 / 36 / 32  3             17             8 of 9
  0.5   3-5       36 / 33 / 30  6             18             7 of 9
  0.25  0-2       36 / 36 / 34  2             18             9 of 9
  0.25  3-5       36 / 36 / 35  1             19             8 of 9
  0.25  6-8       36 / 36 / 33  3             18             9 of 9
  0     0-2       36 / 36 / 35  1             18             9 of 9
  0     3-5       36 / 36 / 35  1             18             9 of 9
  ===== ========= ============= ============= ============== =====================

  At a quarter of Eq 6.4-6.11's noise or less the issue's targets along A, B and the
  viewpoints, and for wrong decisions, hold on all three seed sets. Maps and presentations each
  cost about half of the loss at S = 1 (seeds 0-2, :func:`map_job` given another S than the
  presentations, 2026-12-06): maps at 0.25 presented at 1, 36 / 30 / 27 and 5 wrong; maps at 1
  presented at 0.25, 35 / 31 / 26 and 11 wrong (the distorted maps bring the wrong decisions); the novel-object target holds
  at none: the hollow bucket is named the barrel (its outer wall lies a median 7-9 mm from the
  barrel's surface, and the pose hypotheses, free to shift and tilt, fit its contacts to the
  barrel's map within 5 mm: ``tolerance_m`` 5 or 6 mm instead of 8 changed no decision at
  S = 0.25, seeds 0-2), the mushroom and the knot stay undecided. Nor does the spread of the
  window's residuals tell it apart (2026-12-06, S = 0.25, seed 0, every impulse logged with its
  window's residuals): a rule that an impulse's 90th-percentile residual be at most 15 mm keeps
  293 of the bucket's 600 impulses for the barrel (49 %) and 4,888 of the library objects' 7,565
  own ones (65 %; the Box 35 %, the Barrel 92 %), and the share of residuals over 8 or 15 mm, or
  the 75th percentile, separate no better: from outside the bucket is the barrel. Below S = 1 the surface path's noise models follow S, never below
  :data:`maps.pose_graph.MIN_NOISE_SCALE` (0.25): the matcher's motion model (:func:`surface_targets`)
  and the odometry edges of each map's pose graph (:func:`map_job`), by their ``for_odometry_scale``. Without the floor, S = 0 ruled every
  object out after a few impulses (seeds 0-2: 33 / 32 / 25, novel 24); with the graph's edges at
  the full noise, S = 0 on seeds 3-5 gave 34 / 34 / 32 and 7 wrong (re-localisations that
  disagreed with exact odometry bent the barrel's, the mug's and the jug's maps: presented along
  A itself, 35-58 % of their contacts fell where their maps felt nothing). At S = 1 both are as
  before.
  The study's default stays Eq 6.4-6.11 (the thesis' Ch.6 noise; its Ch.5 data took theirs from
  the physical data set, Sec 5.2.1, whose figures are not printed).

``cansim study recognition --quick`` (both matchers, 12 objects, seed 0; 36 s wall with
warm caches on a quiet machine, 2026-12-05 - 35 s with warm and 53 s with empty caches
before the poses reached for contact; 3.6-4.5 min at load 2-4), correct IC decisions thesis / surface:

* Eq 6.4-6.11's odometry noise (the default): along A 11/12 / 12/12, along B 0/12 / 7/12,
  viewpoints 0/12 / 7/12, novel objects without a decision 9/9 / 5/9, wrong decisions
  (another library object) 0/36 / 2/36 (re-run 2026-12-06; 8/12 and 3/36 were said before,
  and the same command gives 7 and 2 at the commit that said so) - the surface matcher names more objects, and
  makes a few wrong decisions where the thesis' makes none; the own map leads every run
  along A for both. (Since the matcher's filters draw from one random stream per object,
  2026-12-05, :mod:`maps.surface_match` Status; before, with one stream for all: surface
  viewpoints 8/12, novel 6/9, wrong 1/36; over nine matcher-seed replays of seeds 0-2 the
  two are the same within the seed spread. Novel 7/9 -> 5/9 when objects that fit too badly
  began to be dropped, the same day: ``prune_residual_ratio``, also within that spread. The figures of the bullets below were measured
  with the one stream.)
* **Poses that reach for 3 whiskers** (``REACH_CONTACTS``, 2026-12-05; the number chosen
  beforehand, the regions of Eq 5.5 needing 3 contacts; nothing tuned): ``--quick --seeds
  3`` (thresholds calibrated on seed 0, the study's matcher seeds), fixed standoff ->
  reaching: region observations in 70 % -> 86 % of the whisks; thesis matcher along A 28 ->
  33/36 (own map leading in 36/36 both), B 1 -> 0, viewpoints 0 -> 0, novel undecided 27/27,
  wrong 0 both; surface matcher along A 32 -> 36/36 (leading 33 -> 36), B 22 -> 24,
  viewpoints 19 -> 19, wrong 9 -> 7 of 108, novel undecided 19 -> 18 of 27; held-out seeds
  1-2 alone: A 22 -> 24/24, B 14 -> 16, viewpoints 12 -> 11, wrong 7 -> 6 of 72, novel 13 ->
  12 of 18. The same whisks replayed with three matcher seeds each (nine runs; of 108 along A
  / B / viewpoints, wrong of 324, novel undecided of 81): A 97 -> 107 (own map leading 101
  -> 107; the one miss a Jug taken for the Kettle, seed 1), B 65 -> 72, viewpoints 54 -> 49,
  wrong 31 -> 32, novel 59 -> 56 - along A and B better, from the viewpoints (each mapping
  pose moved 5-10 cm and turned, the advance kept) a little worse. The figures below were
  measured at the fixed standoff. Before the
  registration-refined proposal (``SurfaceMatchConfig.refine_iterations``, default 1 since
  2026-12-04; ``refine_iterations=0`` gives the earlier matcher) the same run gave along B
  5/12 and 6 wrong decisions of 36. Held-out seeds 1-2 in a full run's setting
  (thresholds calibrated on seed 0), the study's matcher seeds: along A 19 -> 22/24, B
  14 -> 14/24, viewpoints 8 -> 12/24, wrong 20 -> 7/72, novel undecided 10 -> 13/18
  (blind -> refined; three matcher seeds: B + viewpoints 67 -> 76 of 144, wrong 54 -> 25
  of 216). The bullets below were measured before it;
* a quarter of it (``--odometry-noise 0.25``): along A 9/12 / 12/12, along B 1/12 / 11/12,
  viewpoints 0/12 / 10/12, novel 9/9 / 6/9 (the hollow bucket taken for the barrel in all
  three presentations), wrong 0/36 / 1/36 (the Box from viewpoints taken for the Box-Stack);
  the duck, touched on 38-42 % of its whisks, is not named along B or the viewpoints.
  Replayed offline on held-out seeds 1-2: along B 21/24, viewpoints 20/24, 3 wrong of 48.
* held-out seeds 1-2 at Eq 6.4-6.11's noise (the study's functions, surface matcher,
  2026-12-04, ``run(seeds=(1, 2))``, which calibrates T_pfh / T_sda on seed 1): along A
  20/24, along B 16/24, viewpoints 14/24, wrong 11/72, novel objects undecided 10/18 -
  seed 0's B (5/12) is its lowest. The same seeds in a full run (``run(seeds=(0, 1, 2))``,
  thresholds calibrated on seed 0): 19/24, 14/24, 8/24, wrong 20/72, novel 10/18 - the
  calibration seed moves these figures more than mapping loops, particles or longer
  presentations do (:mod:`maps.surface_match`, Status).
* **Tried and not kept: pooled threshold calibration** (2026-12-04, surface matcher,
  2 loops, 200 particles). One seed's T_pfh / T_sda (0.75 quantile of 94-96 same-pose
  pairs) vary with the seed: seeds 0-9 give T_pfh 0.787-1.059 (sd 0.092), T_sda
  0.260-0.373 (sd 0.041), seed 0's T_sda the third highest; so a run's figures depended on
  the seed it starts with. ``--calibration pooled`` (``run(calibration="pooled")``) takes
  the :data:`CALIBRATION_QUANTILE` (0.80) quantile of the same-pose distances of
  :data:`CALIBRATION_SEEDS` (5) calibration seeds ``derive_seed(0, "calibration", i)``
  (478 pairs: 1.010 / 0.325), the same for every run. k and the quantile were chosen on
  seeds 0-1 among k = 3 / 5 at the 0.75 quantile (0.934 / 0.285 and 0.917 / 0.284: B +
  viewpoints 20 and 19 of 48 against seed 0's rule's 23, wrong 19 of 72 as it), the median of five
  seeds' thresholds (19, 19), k = 5 at 0.80 (23, 18) and 0.85 (24, 22). Judged on held-out seeds 3-5
  against seed 0's thresholds (what a full run uses), three matcher seeds each (A, B,
  viewpoints of 108, wrong of 324, novel undecided of 81): seed 0's 93, 47, 49, 93, 47;
  pooled 89, 52, 48, 95, 43 - B + viewpoints 100 against 96 of 216, but 2 more wrong
  decisions, 4 fewer along A, 4 more novel objects named: not better. Per seed (matcher
  seed 0, A / B / viewpoints / wrong / novel): seed 0's rule 10/3/5/14/7, 9/8/5/10/5,
  10/4/6/13/6; pooled 9/5/5/13/6, 9/7/7/8/4, 10/5/5/13/5. The pooling narrows the
  thresholds (four disjoint pools of five at 0.80: T_pfh 0.982-1.087, T_sda 0.325-0.409,
  against 0.838-1.133 and 0.291-0.425 for seeds 0-9 alone) but not the figures: on the held-out seeds the
  other three pools give B + viewpoints 30-32 of 72 and 35-38 of 108 wrong (matcher seed
  0), against 34 / 34 for the chosen pool and 31 / 37 for seed 0's. Seed 1's thresholds,
  better than seed 0's on seeds 1-2 (bullet above), are worse on seeds 3-5 (B + viewpoints
  26 against 31 of 72, wrong 37 both): which thresholds help changes with the seeds they
  are judged on. ``cansim study recognition --quick --calibration pooled``: surface A 10/12,
  B 5/12, viewpoints 6/12, wrong 8/36, novel 5/9 undecided; thesis 9/12, 0/12, 0/12, 0/36,
  9/9. Reproduce: ``run(out, seeds=(3, 4, 5), bins=("vp 5-10 cm",), matchers=("surface",),
  calibration="pooled")`` against ``calibration=[0], calibration_quantile=0.75`` (matcher
  seed 0; the other two matcher seeds add 1 and 2 to :class:`~maps.surface_match.SurfaceMatchConfig`'s seed).

* **What the maps never felt limits the surface matcher, not their warp alone**
  (2026-12-05, seed 0, offline replays of the study's whisks, refined matcher, three
  matcher seeds; correct of 36 along B / viewpoints, wrong decisions): the study's maps
  22 / 21, wrong 2 / 4; library surfaces felt at the *true* poses (one 200-whisk pass of
  A) 22 / 23, wrong 0 / 5; those surfaces and *exact* odometry (one matcher seed) 8 / 8 of
  12. The misses are the same objects every time (duck, jug, Blob, Skull; the Plane along
  B): placed at their true poses, 10-43 % of their contacts from the viewpoints lie where
  the own map felt nothing (``unmapped_contact_fraction``, a column of the runs' CSV), each
  costing the own object ``log(outlier_weight)`` (3 nats), while a large smooth object
  (Barrel, Kettle) fits them 10-15 mm off at every contact. Tried and not kept: the same
  flat likelihood for every contact where a map has nothing (0.15 or 0.35 of a perfect fit
  instead of 0.05): every decision is lost (along A 22 then 0 of 36) - the hypotheses of
  every object flee to where their map is silent and all objects tie.

The issue's targets (90 % along B and the viewpoints, 95 % of novel objects undecided)
are not reached; :mod:`maps.surface_match` (Status) says what limits each.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from cansim.seeding import derive_seed
from cansim.studies.object_options import (add_mesh_options, check_distinct, check_mesh_options, conform_objects,
                                           is_mesh_file, labelled_rows, object_label, object_labels, seed_name)
from cansim.studies.process_pool import pool_map
from maps.recognition import MATCHERS  # thesis | surface
from whisker_io.command_line import CommandParser
from whisker_io.errors import InvalidInputError
from whisker_io.persistence import write_atomically, write_csv
from whisker_io.sim.trajectories import REACH_CONTACTS as TRAJECTORY_REACH_CONTACTS

logger = logging.getLogger(__name__)

#: IC decision threshold (thesis Sec 6.2).
IC_THRESHOLD = 300.0
#: Viewpoint bins: (label, distance to the nearest mapping pose (m, lo-hi), rotation (deg, lo-hi)).
VIEWPOINT_BINS: tuple[tuple[str, tuple[float, float], tuple[float, float]], ...] = (
    ("vp 2-5 cm", (0.02, 0.05), (2.0, 5.0)),
    ("vp 5-10 cm", (0.05, 0.10), (5.0, 15.0)),
    ("vp 10-15 cm", (0.10, 0.15), (15.0, 25.0)),
)
#: The confusion figure's last column: the runs that decided nothing (no object label has brackets).
NO_DECISION = "(no decision)"
#: The matchers a run uses unless told (``--matchers``).
DEFAULT_MATCHERS = ("thesis", "surface")
COLUMNS = ("seed", "library_size", "matcher", "presented", "novel", "presentation", "distance_bin",
           "median_distance_m", "median_rotation_deg", "whisks", "whisks_with_contact", "decision", "correct",
           "decision_whisk", "final_ic_own", "final_ic_best_other", "impulses_own", "impulses_other",
           "unmapped_contact_fraction", "roll_deg", "mesh_file")
#: Contact model and noise of the maps and the presentations (module docstring).
CONTACT_MODEL = "tip"
NOISE_SCALE = 0.3
#: Calibration rules of T_pfh / T_sda (``run(calibration=...)``, ``--calibration``):
#: ``first-seed`` (the default) calibrates on the run's first seed alone, as the study
#: always has; ``pooled`` pools the same-pose distances of :data:`CALIBRATION_SEEDS`
#: calibration seeds (:func:`calibration_seeds`, never a seed the study maps or presents),
#: tried on 2026-12-04 and not made the default (module docstring, Status).
CALIBRATIONS = ("first-seed", "pooled")
#: Calibration seeds pooled by the ``pooled`` rule (module docstring, Status).
CALIBRATION_SEEDS = 5
#: Quantile of the pooled same-pose distances taken as T_pfh / T_sda (``pooled`` and explicit
#: calibration seeds; ``first-seed`` keeps the Ch.5 study's 0.75). Chosen on seeds 0-1: at 0.75
#: the five pooled seeds give lower thresholds than seed 0's (0.917 / 0.284 against 0.996 /
#: 0.352) and fewer correct decisions along B and the viewpoints (Status).
CALIBRATION_QUANTILE = 0.80


#: Whiskers the recognition study's trajectories reach for (:func:`run`'s ``reach_contacts``):
#: :data:`whisker_io.sim.trajectories.REACH_CONTACTS`, a region of Eq 5.5
REACH_CONTACTS = TRAJECTORY_REACH_CONTACTS


@dataclass(frozen=True)
class Setup:
    """Everything a worker needs (picklable)."""

    seed: int
    map_loops: int
    whisks: int
    thresholds: tuple[float, float]
    out: str
    matchers: tuple[str, ...] = ("thesis",)
    odometry_scale: float = 1.0
    reach_contacts: int = REACH_CONTACTS
    #: ``(object, roll)`` pairs: the array's roll about its axis on each object's trajectories, deg
    #: (:func:`roll_job`); an object not listed is whisked at the thesis' 90 deg
    rolls_deg: tuple[tuple[str, float], ...] = ()

    def roll_of(self, name: str) -> float:
        """The roll (deg) of ``name``'s mapping and presentation trajectories."""
        return dict(self.rolls_deg).get(name, 90.0)


def roll_job(job: tuple[str, int]) -> tuple[str, float]:
    """``(name, roll)``: :func:`whisker_io.sim.trajectories.reaching_roll_deg` of one object on
    trajectory A at the study's step, reaching for ``job[1]`` whiskers (0: the thesis' 90 deg)."""
    from whisker_io.sim.catalogue import resolve_object
    from whisker_io.sim.trajectories import reaching_roll_deg

    name, reach = job
    if reach < 1:
        return name, 90.0
    step_m, step_deg = _ch5().STEP
    return name, reaching_roll_deg(resolve_object(name).mesh, "A", reach, step_m=step_m, step_deg=step_deg)


# ------------------------------------------------------------------ viewpoints
def viewpoint_set(poses: Sequence[Any], centre_m: np.ndarray, rng: np.random.Generator,
                  distance_m: tuple[float, float], rotation_deg: tuple[float, float], tries: int = 50) -> list[Any]:
    """Each pose moved tangentially about ``centre_m`` and turned about a random axis.

    The translation is drawn until the moved pose's distance to the nearest pose of
    ``poses`` lies in ``distance_m`` (at most ``tries`` draws; the last draw is kept),
    the rotation angle uniformly in ``rotation_deg``.

    Parameters
    ----------
    poses : sequence of Pose
        The mapping poses.
    centre_m : ndarray, shape (3,)
        The object's centre (m), about which the moves are tangential.
    rng : numpy.random.Generator
    distance_m, rotation_deg : (float, float)
        The bin (m, degrees).

    Returns
    -------
    list of Pose, one per mapping pose, in the mapping order.
    """
    from scipy.spatial.transform import Rotation

    from whisker_io.pose import Pose

    positions = np.array([p.position_m for p in poses])
    out = []
    for p in poses:
        radial = p.position_m - centre_m
        radial = radial / max(np.linalg.norm(radial), 1e-12)
        moved = p.position_m
        for _ in range(tries):
            d = rng.normal(size=3)
            d -= d.dot(radial) * radial
            d /= max(np.linalg.norm(d), 1e-12)
            moved = p.position_m + d * rng.uniform(*distance_m)
            nearest = np.min(np.linalg.norm(positions - moved, axis=1))
            if distance_m[0] <= nearest <= distance_m[1]:
                break
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        turn = Rotation.from_rotvec(axis * math.radians(rng.uniform(*rotation_deg)))
        out.append(Pose.from_rotation(moved, turn * p.rotation))
    return out


def nearest_distances(poses: Sequence[Any], mapping: Sequence[Any]) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m) and rotation (deg) of each pose to its nearest mapping pose (by position)."""
    positions = np.array([m.position_m for m in mapping])
    d = np.empty(len(poses))
    r = np.empty(len(poses))
    for i, p in enumerate(poses):
        j = int(np.argmin(np.linalg.norm(positions - p.position_m, axis=1)))
        d[i], rot = p.distance_to(mapping[j])
        r[i] = math.degrees(rot)
    return d, r


# ------------------------------------------------------------------ jobs
def _ch5():
    from cansim.studies import ch5_object_maps

    return ch5_object_maps


def _settings(setup: Setup) -> Any:
    ch5 = _ch5()
    return ch5.StudyConfig(n_loops=setup.map_loops, noise_scale=NOISE_SCALE,
                        thresholds={CONTACT_MODEL: setup.thresholds}, radial_model=None, seed=setup.seed,
                        odometry_scale=setup.odometry_scale, reach_contacts=setup.reach_contacts,
                        reach_when_missed=False)  # reach_contacts 0: the fixed standoff for every object


def map_job(job: tuple[str, Setup] | tuple[str, Setup, str]) -> dict[str, Any]:
    """Map one library object along trajectory A; the saved model's path and its stored surface's.

    ``job`` is ``(name, setup)`` or ``(name, setup, stem)``: the files are
    ``maps/seed<seed>/<stem>.npz`` and ``<stem>_surface.npz``, the stem by default
    :func:`whisker_io.sim.catalogue.object_file_name` of the name (:func:`run` passes the object's
    label, :func:`~whisker_io.sim.catalogue.object_labels` of every object of the run: distinct).

    The model is :func:`cansim.studies.ch5_object_maps.map_object`'s, as the Ch.5 study
    builds it (same seed, same whisks). Its stored surface (what was felt, placed by the whisk poses of
    the mapping run optimised as a pose graph, :func:`maps.pose_graph.whisk_surface`,
    in the arm's frame: the first whisk's true pose is the map's anchor) is saved next to
    it for the ``surface`` matcher.
    """
    from maps.pose_graph import WhiskGraphConfig, whisk_surface
    from whisker_io.sim.catalogue import object_file_name

    ch5 = _ch5()
    name, setup = job[0], job[1]
    stem = job[2] if len(job) > 2 else object_file_name(name)
    path = Path(setup.out) / "maps" / f"seed{setup.seed}" / f"{stem}.npz"
    path.parent.mkdir(parents=True, exist_ok=True)
    slam, poses, log = ch5.map_object(name, ch5.Config("both", False, CONTACT_MODEL), _settings(setup), step=ch5.STEP,
                                      roll_deg=setup.roll_of(name))
    slam.save(path)
    graph = WhiskGraphConfig().for_odometry_scale(setup.odometry_scale)  # odometry edges as noisy as the odometry
    points, seen = whisk_surface(log["odometry"], log["exp_ids"], log["relocalised"], log["contacts"], graph,
                                 with_viewpoints=True, anchor=poses[0])
    surface_path = path.with_name(path.stem + "_surface.npz")
    write_atomically(surface_path, lambda fh: np.savez_compressed(fh, points_m=points, viewpoints_m=seen))
    return {"name": name, "path": str(path), "surface": str(surface_path), "n_experiences": slam.object_map.n_experiences,
            "n_points": int(len(points)), "whisks": len(poses)}


def present_job(job: tuple[str, bool, str, tuple[str, tuple[float, float], tuple[float, float]] | None,
                Sequence[str], Sequence[str], Setup, Any]) -> list[dict[str, Any]]:
    """Explore ``presented`` along A, B or a viewpoint set against the library; one CSV row per matcher.

    Every matcher of ``setup.matchers`` sees the same whisks (poses, contacts, noisy
    odometry): ``thesis`` the re-localisations of the appended library model,
    ``surface`` the impulses of :class:`maps.surface_match.SurfaceMatcher` replaying the
    whisks against the library's stored surfaces (started at the presentation's first
    pose, as the Ch.5 runs start the pose cells at a known place); both decide at
    :data:`IC_THRESHOLD` with the same leaky integrators (:mod:`maps.recognition`).
    """
    from maps.recognition import (
        LeakyIntegrator,
        confidence,
        decide,
        integrated_confidence,
        relocalisation_targets,
    )
    from whisker_io.sim.catalogue import resolve_object
    from whisker_io.sim.trajectories import object_trajectory

    ch5 = _ch5()
    presented, novel, presentation, vp_bin, paths, names, setup, library = job
    mesh = resolve_object(presented).mesh
    step_m, step_deg = ch5.STEP  # the same step for every object, the Box too (module docstring)
    family = "B" if presentation == "B" else "A"
    # whisked as map_job maps it (ch5.map_object): the same rule, one function
    reach, roll = ch5.trajectory_choice(mesh, _settings(setup), step_m, step_deg, setup.roll_of(presented))
    loop = object_trajectory(mesh, family, 1, step_m=step_m, step_deg=step_deg, reach_contacts=reach, roll_deg=roll)
    poses = loop * max(1, math.ceil(setup.whisks / len(loop)))  # whole loops (object_trajectory repeats one loop)
    rng = np.random.default_rng(derive_seed(setup.seed, "present", seed_name(presented), presentation,
                                            vp_bin[0] if vp_bin else ""))
    mapping = loop if family == "A" else object_trajectory(mesh, "A", 1, step_m=step_m, step_deg=step_deg,
                                                           reach_contacts=reach, roll_deg=roll)
    if vp_bin is not None:
        centre = np.asarray(mesh.bounding_box.centroid, dtype=float)
        poses = viewpoint_set(poses, centre, rng, vp_bin[1], vp_bin[2])
    dist, rot = nearest_distances(poses, mapping)
    slam, lib = ch5.library_model(paths, names, cell_size_m=step_m, warn_empty=False)  # run() says it once
    chain = ch5._chain(mesh, CONTACT_MODEL, NOISE_SCALE)
    log = ch5.explore(slam, chain, poses, rng, setup.odometry_scale)
    params = LeakyIntegrator()
    own = names.index(presented) if presented in names else -1
    others = [j for j in range(len(names)) if j != own]
    unmapped = (unmapped_contact_fraction(library, own, log["true_p"], log["true_q"], log["contacts"])
                if library is not None and own >= 0 else "")
    rows = []
    for matcher in setup.matchers:
        if matcher == "thesis":
            table = lib.with_explored(slam.object_map.n_experiences)
            targets = relocalisation_targets(log["exp_ids"], log["relocalised"], table)
        else:
            targets = surface_targets(library, poses[0], log["odometry"], log["contacts"],
                                      odometry_scale=setup.odometry_scale,
                                      seed=derive_seed(setup.seed, "surface", seed_name(presented), presentation))
        ic = integrated_confidence(confidence(targets, len(names), params), params)
        k = decide(ic, IC_THRESHOLD)
        crossing = None if k is None else int(np.flatnonzero(ic[:, k] >= IC_THRESHOLD)[0])
        rows.append({
            "seed": setup.seed, "library_size": len(names), "matcher": matcher, "presented": presented,
            "novel": novel, "presentation": presentation if vp_bin is None else "viewpoints",
            "distance_bin": "" if vp_bin is None else vp_bin[0],
            "median_distance_m": float(np.median(dist)), "median_rotation_deg": float(np.median(rot)),
            "whisks": len(poses), "whisks_with_contact": int(log["n_observations"]),
            "decision": "" if k is None else names[k],
            "correct": (k is None) if novel else (k == own),
            "decision_whisk": "" if crossing is None else crossing,
            "final_ic_own": float(ic[-1, own]) if own >= 0 else "",  # a novel object has no map of its own
            "final_ic_best_other": float(ic[-1, others].max()) if others else 0.0,
            "impulses_own": int(np.sum(targets == own)) if own >= 0 else 0,
            "impulses_other": int(np.sum((targets >= 0) & (targets != own))),
            "unmapped_contact_fraction": unmapped,
            "roll_deg": roll,
        })
    return rows


def unmapped_contact_fraction(library: Any, index: int, true_p: Any, true_q: Any, contacts: Sequence[Any]) -> float:
    """Share of a presentation's contacts, placed at their true poses, where object ``index``'s map felt nothing.

    A contact is *unmapped* when the object's stored surface reads its cap there: no stored
    contact within reach (cells over ``2 smoothing_m`` from every stored point, or off the
    grid; :mod:`maps.surface_field`). It describes the map, not a matcher, and has two
    causes: parts of the object the mapping path never touched, and parts the map placed
    more than about 3 cm off (its warp, :mod:`maps.pose_graph`). Measured 2026-12-05 (the
    study's maps, 2 loops of A, Eq 6.4-6.11's noise; median over the 12 objects, seeds 0 /
    1 / 2): along A 23 / 27 / 18 %, along B 22 / 36 / 20 %, viewpoints 5-10 cm 31 / 31 /
    27 % (the duck, jug, kettle and torus the most, up to 79 %). With surfaces felt at the
    true poses (one 200-whisk pass of A, seed 0) the warp is gone and what is left is the
    path: along B 5-22 %, from the viewpoints 10-43 % (Mug, Blob, Skull, Jug, duck).

    Parameters
    ----------
    library : maps.surface_match.SurfaceLibrary
    index : int
        The presented object's place in the library.
    true_p : array_like (n, 3)
        The whisks' true end-effector positions in the library's frame, m.
    true_q : array_like (n, 4)
        Their orientations (quaternions x, y, z, w).
    contacts : sequence (n,) of array_like (k, 3) or None
        Each whisk's contacts in the end-effector frame, m.

    Returns
    -------
    float
        In [0, 1]; 0 for a presentation without contacts.

    Raises
    ------
    InvalidInputError, ShapeError
        Not a surface library, an index outside it, poses or contacts of other shapes or
        lengths, non-finite values, quaternions that are not unit.
    """
    from scipy.spatial.transform import Rotation

    from maps.surface_match import SurfaceLibrary
    from whisker_io.errors import InvalidInputError, ShapeError
    from whisker_io.validation import finite_array

    if not isinstance(library, SurfaceLibrary):
        raise InvalidInputError(f"library must be a SurfaceLibrary (load_surface_library), got {type(library).__name__}")
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < library.n_objects:
        raise InvalidInputError(f"index must be an object of the library, 0..{library.n_objects - 1}; got {index!r}")
    p = finite_array(true_p, (None, 3), "true_p")
    q = finite_array(true_q, (len(p), 4), "true_q")
    cs = list(contacts)
    if len(cs) != len(p):
        raise ShapeError(f"need one contact array (or None) per pose ({len(p)}), got {len(cs)}")
    if len(q) and np.any(np.abs(np.linalg.norm(q, axis=1) - 1.0) > 1e-6):
        raise InvalidInputError("true_q must hold unit quaternions (x, y, z, w)")
    felt = [p[k] + Rotation.from_quat(q[k]).apply(finite_array(c, (None, 3), f"contacts[{k}]"))
            for k, c in enumerate(cs) if c is not None]
    x = np.concatenate([np.zeros((0, 3))] + felt)
    if not len(x):
        return 0.0
    fields = library.fields
    d = fields.distance(x, np.full(len(x), int(index), dtype=np.int64))
    return float(np.mean(d >= fields.config.cap_m))


def load_surface_library(surfaces: Sequence[str | Path], names: Sequence[str]) -> Any:
    """The library objects' stored surfaces (files written by :func:`map_job`) as one
    :class:`maps.surface_match.SurfaceLibrary` (its grids built once, for every presentation).

    Parameters
    ----------
    surfaces : sequence of path
        Each library object's stored surface (``points_m`` in the arm's frame and
        ``viewpoints_m``, where each was felt from; files without it orient the normals
        between neighbours), in the order of ``names``.
    names : sequence of str

    Raises
    ------
    InvalidInputError, CorruptFileError, ShapeError
        A missing file, a file that is not a stored surface, malformed points.
    """
    import zipfile

    from maps.surface_match import SurfaceLibrary
    from whisker_io.errors import CorruptFileError, InvalidInputError

    points, seen = [], []
    for f in surfaces:
        try:
            with np.load(f) as z:
                points.append(z["points_m"])
                seen.append(z["viewpoints_m"] if "viewpoints_m" in z.files else None)
        except FileNotFoundError:
            raise InvalidInputError(f"{f}: no such surface file (map the object first: the study's map_job writes it)") from None
        except (KeyError, OSError, ValueError, zipfile.BadZipFile) as exc:
            raise CorruptFileError(f"{f}: not a stored-surface file with points_m ({exc})") from None
    for name, pts in zip(names, points):  # the grid's limit, named for the object and the command line
        pts = np.asarray(pts)
        if pts.ndim == 2 and pts.shape[1] == 3 and len(pts) and pts.dtype.kind == "f" and np.isfinite(pts).all():
            _check_surface_grid(name, np.array([pts.min(axis=0), pts.max(axis=0)]), drift_m=0.0, what="its map")
        # (malformed points: SurfaceLibrary says what is wrong with them)
    return SurfaceLibrary(points, names, seen)


def surface_targets(library: Any, start_pose: Any, odometry: Sequence[Any], contacts: Sequence[Any],
                    odometry_scale: float = 1.0, seed: int = 0) -> np.ndarray:
    """The object each whisk's surface-matcher impulse went to (-1: none), (n_whisks,) int.

    Parameters
    ----------
    library : SurfaceLibrary
        The library's stored surfaces (:func:`load_surface_library`).
    start_pose : Pose
        The arm's pose at the first whisk.
    odometry : sequence of SpatialOdometry
        Per whisk (the first is ignored: the matcher starts at ``start_pose``).
    contacts : sequence of ndarray (k, 3) or None
        Per whisk, end-effector frame, m.
    odometry_scale : float
        The odometry's noise as a multiple of Eq 6.4-6.11's: the matcher's motion model, at
        least :data:`maps.pose_graph.MIN_NOISE_SCALE` times it
        (:meth:`~maps.surface_match.SurfaceMatchConfig.for_odometry_scale`).
    seed : int
        Seed of the matcher's hypotheses.
    """
    from maps.surface_match import SurfaceMatchConfig, SurfaceMatcher

    cfg = replace(SurfaceMatchConfig().for_odometry_scale(odometry_scale), seed=seed)
    matcher = SurfaceMatcher(library, np.r_[start_pose.position_m, start_pose.quaternion_xyzw], cfg)
    out = np.full(len(contacts), -1, dtype=np.int64)
    for i, (odo, pts) in enumerate(zip(odometry, contacts)):
        imp = matcher.step(odo if i else None, pts)
        if imp.any():
            out[i] = int(np.argmax(imp))
    return out


# ------------------------------------------------------------------ the study
def calibration_seeds(k: int = CALIBRATION_SEEDS, base: int = 0) -> tuple[int, ...]:
    """The seeds whose same-pose distances the ``pooled`` calibration pools.

    ``derive_seed(base, "calibration", i)`` for ``i < k``: fixed, whatever seeds a run
    maps and presents, so every run of the study (any ``seeds``) matches with the same
    T_pfh / T_sda, and no seed the study is measured on chooses them.

    Parameters
    ----------
    k : int
        Number of calibration seeds, >= 1.
    base : int
        Base seed of the derivation.

    Returns
    -------
    tuple of int, length ``k``, each in ``[0, 2**32)``.

    Raises
    ------
    cansim.errors.InvalidInputError
        ``k`` not an integer >= 1, or ``base`` not an integer.
    """
    from cansim.errors import InvalidInputError
    from whisker_io.validation import config_field

    config_field(k, "k", int, minimum=1, error=InvalidInputError)
    config_field(base, "base", int, error=InvalidInputError)
    return tuple(derive_seed(int(base), "calibration", i) for i in range(int(k)))


def _calibration_seeds(calibration: str | Sequence[int], seeds: Sequence[int]) -> int | Sequence[int]:
    """The seed(s) :func:`calibrated_thresholds` calibrates on; a bad rule or no seed is refused here, before any
    work (:func:`run` asks before it writes anything)."""
    from cansim.errors import ConfigError, InvalidInputError

    if not isinstance(calibration, str):
        return calibration
    if calibration not in CALIBRATIONS:
        raise ConfigError(f"calibration must be one of {CALIBRATIONS} or a sequence of seeds, got {calibration!r}")
    if calibration == "pooled":
        return calibration_seeds()
    if not len(seeds):
        raise InvalidInputError("calibration 'first-seed' needs at least one seed in seeds")
    return seeds[0]


def calibrated_thresholds(calibration: str | Sequence[int], seeds: Sequence[int],
                          quantile: float | None = None) -> tuple[float, float]:
    """(T_pfh, T_sda) of the maps (tip contacts, :data:`NOISE_SCALE`), dimensionless.

    Parameters
    ----------
    calibration : str or sequence of int
        ``"first-seed"`` (``seeds[0]`` alone, the study's default), ``"pooled"``
        (:func:`calibration_seeds`), or the calibration seeds to pool.
    seeds : sequence of int
        The run's seeds.
    quantile : float, optional
        Quantile of the same-pose distances, in (0, 1]; default
        :data:`CALIBRATION_QUANTILE` for pooled seeds, 0.75 for ``first-seed`` (as the Ch.5 study).

    Raises
    ------
    cansim.errors.ConfigError
        An unknown rule name.
    cansim.errors.InvalidInputError
        No seeds for ``first-seed``, or bad calibration seeds
        (:func:`cansim.studies.ch5_object_maps.calibrate`).
    """
    cal_seeds = _calibration_seeds(calibration, seeds)
    if quantile is None:
        quantile = 0.75 if calibration == "first-seed" else CALIBRATION_QUANTILE
    cal = _ch5().calibrate(NOISE_SCALE, quantile, cal_seeds, CONTACT_MODEL)
    logger.info("T_pfh %.4f, T_sda %.4f: %g quantile of %d same-pose pairs (calibration %s)", cal["pfh_threshold"],
                cal["sda_threshold"], quantile, cal["n_pairs"], calibration)
    return (cal["pfh_threshold"], cal["sda_threshold"])


def run(out: Path, objects: Sequence[str] | None = None, novel: Sequence[str] | None = None,
        library_sizes: Sequence[int] = (12,), seeds: Sequence[int] = (0,), bins: Sequence[str] | None = None,
        map_loops: int = 2, whisks: int = 200, workers: int = 2, progress: bool = True,
        matchers: Sequence[str] = DEFAULT_MATCHERS, odometry_scale: float = 1.0,
        calibration: str | Sequence[int] = "first-seed",
        calibration_quantile: float | None = None, reach_contacts: int = REACH_CONTACTS,
        roll_deg: float | None = None, scale_to_m: float | Sequence[float] | None = None,
        up_axis: str | Sequence[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark; returns the CSV rows (also written to ``out`` as ``recognition_runs.csv``; the figures
    and the summary are :func:`figures` and :func:`summary` of the rows, as :func:`main` writes them).

    Parameters
    ----------
    out : Path
        Output folder (maps are saved under ``out/maps``).
    objects : sequence of str, optional
        Library objects (names or mesh files); default :func:`whisker_io.sim.shapes.library_names` of the
        largest ``library_sizes``.
    novel : sequence of str, optional
        Objects presented but never mapped (default: three of
        :func:`whisker_io.sim.shapes.novel_names`).
    library_sizes : sequence of int
        Library sizes; the presentations along A, B and the viewpoint sets run on the
        smallest, the larger ones are presented along B only (the size figure).
    seeds : sequence of int
        Seeds (maps, noise and viewpoints are drawn per seed).
    bins : sequence of str, optional
        Labels of :data:`VIEWPOINT_BINS` to run (default all).
    map_loops : int
        Loops of trajectory A per map.
    whisks : int
        Least whisks per presentation (whole loops).
    matchers : sequence of str
        Of :data:`MATCHERS`; every presentation is decided by each (same whisks).
    odometry_scale : float
        Odometry noise of the maps and the presentations as a multiple of Eq 6.4-6.11's
        (1 = the thesis' Sec 6.1.3.1.1 values), in [0, 10].
    calibration : str or sequence of int
        How T_pfh / T_sda of the maps are calibrated (:func:`calibrated_thresholds`):
        ``"first-seed"`` (default: the 0.75 quantile of the same-pose distances on the
        first of ``seeds``), ``"pooled"`` (the :data:`CALIBRATION_QUANTILE` quantile over
        :data:`CALIBRATION_SEEDS` calibration seeds; Status), or the calibration seeds to pool.
    calibration_quantile : float, optional
        In (0, 1]; default that of the rule (:func:`calibrated_thresholds`).
    reach_contacts : int
        Whiskers every mapping and presentation pose reaches for
        (:func:`whisker_io.sim.trajectories.object_trajectory`, its module docstring item 6;
        default :data:`REACH_CONTACTS`; 0: the fixed standoff, as the Ch.5 study).
    roll_deg : float, optional
        The array's roll about its axis on every trajectory, deg. Default: chosen per object
        (:func:`roll_job`: the thesis' 90 deg unless the object's trajectory A reaches for
        ``reach_contacts`` whiskers clearly more often at 0 deg - flat tori, bowls; 90 deg
        with ``reach_contacts=0``); the CSV's ``roll_deg`` column gives it.
    scale_to_m, up_axis : optional
        Applied to every mesh file of ``objects`` and ``novel``, or one value per mesh file in
        that order (:func:`cansim.studies.object_options.conform_objects`: the changed files are
        run from their copies in ``out/objects``), as ``--scale-to-m`` / ``--up-axis``.

    Raises
    ------
    cansim.errors.ConfigError
        An unknown matcher or calibration rule, ``reach_contacts`` or ``roll_deg`` out of range.
    cansim.errors.InvalidInputError
        Bad calibration seeds or quantile; an object named twice or as both library and novel;
        a mesh file :func:`whisker_io.sim.objects.load_object` refuses.
    """
    from whisker_io.sim.catalogue import resolve_object
    from whisker_io.sim.shapes import library_names, novel_names

    from cansim.errors import ConfigError
    from whisker_io.validation import config_field

    matchers = tuple(dict.fromkeys(matchers))
    if not matchers or any(m not in MATCHERS for m in matchers):
        raise ConfigError(f"matchers must be a non-empty selection of {MATCHERS}, got {list(matchers)}")
    config_field(odometry_scale, "odometry_scale", float, minimum=0.0, maximum=10.0,
                 hint="a multiple of the Eq 6.4-6.11 odometry noise")
    from whisker_io.array.geometry import THESIS_POSITIONS_MM

    reach = config_field(reach_contacts, "reach_contacts", int, minimum=0, maximum=len(THESIS_POSITIONS_MM),
                         hint="whiskers the trajectories reach for, at most the thesis array's (0: the fixed standoff)")
    roll = None if roll_deg is None else config_field(roll_deg, "roll_deg", float, minimum=-360.0, maximum=360.0,
                                                      hint="degrees about the array's axis, or None: per object")
    check_mesh_options([*(objects or ()), *(novel or ())], scale_to_m=scale_to_m, up_axis=up_axis)  # as given
    sizes = sorted(set(int(n) for n in library_sizes))
    everything = list(objects) if objects is not None else list(library_names(sizes[-1]))
    novel = list(novel) if novel is not None else list(novel_names(3))
    # a novel object the library holds, an object named twice: before any work, and before the copies (one
    # file given twice would get two)
    check_distinct(everything, novel)
    _calibration_seeds(calibration, seeds)  # a bad rule before the copies of the mesh files are written
    if any(map(is_mesh_file, (*everything, *novel))):  # mesh files changed by the options: run from their copies
        conformed = conform_objects([*everything, *novel], out / "objects", scale_to_m=scale_to_m, up_axis=up_axis)
        everything, novel = conformed[:len(everything)], conformed[len(everything):]
    for spec in (*everything, *novel):
        mesh = resolve_object(spec).mesh  # a bad name or mesh fails before any work
        if "surface" in matchers and spec in everything:
            _check_surface_grid(spec, mesh.bounds)
    chosen = [b for b in VIEWPOINT_BINS if bins is None or b[0] in bins]
    thresholds = calibrated_thresholds(calibration, seeds, calibration_quantile)  # a bad rule, seed or quantile: before any file
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    labels = object_labels([*everything, *novel])  # one name per object: the CSV's, the summary's, its map file's
    stems = [labels[n] for n in everything]
    whisked = list(dict.fromkeys((*everything, *novel)))  # every object mapped or presented, once
    if roll is None:  # per object, once for every seed (the trajectories do not depend on the seed)
        rolls = tuple(pool_map(roll_job, [(n, int(reach)) for n in whisked], workers, "choosing the rolls", progress))
    else:
        rolls = tuple((n, float(roll)) for n in whisked)
    try:
        for seed in seeds:
            rows += _seed_rows(seed, out, everything, novel, stems, labels, sizes, chosen, thresholds, rolls, map_loops,
                               whisks, matchers, odometry_scale, reach, workers, progress)
    except KeyboardInterrupt:  # the finished seeds' runs are kept (a seed's runs are written whole or not at all)
        done = sorted({r["seed"] for r in rows})
        if rows:  # none finished: an earlier interrupted run's file, if any, is left as it was
            write_csv(out / INTERRUPTED_CSV, COLUMNS, labelled_rows(rows, labels, ("presented", "decision"),
                                                                    of="presented"))
        logger.warning("interrupted: %s (no figures or summary); a complete run writes recognition_runs.csv",
                       f"the runs of {len(done)} finished seed(s) of {len(seeds)} ({', '.join(map(str, done))}) are in "
                       f"{out / INTERRUPTED_CSV}" if rows else "no seed had finished")
        raise
    rows = labelled_rows(rows, labels, ("presented", "decision"), of="presented")
    write_csv(out / "recognition_runs.csv", COLUMNS, rows)
    (out / INTERRUPTED_CSV).unlink(missing_ok=True)  # an earlier interrupted run's rows: this run has them all
    return rows


#: Where an interrupted run (Ctrl-C) keeps the runs of its finished seeds (``recognition_runs.csv``'s columns).
INTERRUPTED_CSV = "recognition_runs_interrupted.csv"


def _seed_rows(seed: int, out: Path, everything: list[str], novel: list[str], stems: list[str], labels: dict[str, str],
               sizes: list[int], chosen: list[Any], thresholds: Any, rolls: tuple[tuple[str, float], ...], map_loops: int,
               whisks: int, matchers: tuple[str, ...], odometry_scale: float, reach: int, workers: int,
               progress: bool) -> list[dict[str, Any]]:
    """One seed of :func:`run`: its maps, then its presentations' rows (unlabelled)."""
    setup = Setup(seed=seed, map_loops=map_loops, whisks=whisks, thresholds=thresholds, out=str(out), matchers=matchers,
                  odometry_scale=float(odometry_scale), reach_contacts=int(reach), rolls_deg=rolls)
    maps = pool_map(map_job, [(n, setup, f) for n, f in zip(everything, stems)], workers, f"mapping (seed {seed})",
                     progress)
    unfelt = [m for m in maps if m.get("n_points", 3) < 3]
    if "surface" in matchers and unfelt:  # the surface matcher needs a felt surface of every library object
        raise InvalidInputError("; ".join(f"the {labels[m['name']]} was touched at {m['n_points']} points in its "
                                          f"{m['whisks']} mapping whisks" for m in unfelt)
                                + ": the surface matcher has no surface to match it against. The study's "
                                "trajectories suit objects about 0.35 m across, in metres and z up (--scale-to-m, "
                                "--up-axis); leave the object out, or run --matchers thesis")
    empty = [m["name"] for m in maps if m["n_experiences"] == 0]
    if empty:  # once per seed: the presentation jobs build the library without repeating it
        logger.warning("seed %d: the map of %s holds no experience (no whisk observed a region of 3 contacts or "
                       "more): the thesis matcher can name nothing as it", seed, ", ".join(labels[n] for n in empty))
    paths = {m["name"]: m["path"] for m in maps}
    surface_paths = {m["name"]: m["surface"] for m in maps}
    jobs = []
    for size in sizes:
        names = everything[:size]
        lib_paths = [paths[n] for n in names]
        kinds = [("A", None), ("B", None), *(("viewpoints", b) for b in chosen)] if size == sizes[0] else [("B", None)]
        # named by seed_name: the matcher's per-object random streams (keyed by name) do not depend on the
        # folder a mesh file was given from, and a registered object's name is its own
        library = (load_surface_library([surface_paths[n] for n in names], [seed_name(n) for n in names])
                   if "surface" in matchers else None)
        for presentation, vp in kinds:
            jobs += [(p, False, presentation, vp, lib_paths, names, setup, library) for p in names]
            jobs += [(p, True, presentation, vp, lib_paths, names, setup, library) for p in novel]
    return [r for rs in pool_map(present_job, jobs, workers, f"presentations (seed {seed})", progress) for r in rs]


def whisks_to_decide(threshold: float = IC_THRESHOLD) -> int:
    """Fewest whisks in which an IC can reach ``threshold``: an impulse at every whisk (the leaky integrator of
    :mod:`maps.recognition` with its defaults); a shorter presentation cannot be decided."""
    from maps.recognition import confidence, integrated_confidence

    n = 64
    while True:
        ic = integrated_confidence(confidence(np.zeros(n, dtype=np.int64), 1))[:, 0]
        if ic[-1] >= threshold:
            return int(np.searchsorted(ic, threshold)) + 1
        n *= 2


#: How far a map's stored surface may lie outside its object's box (m): the drift of maps under the
#: Eq 6.4-6.11 noise (stored surfaces 14-23 mm from the mesh, a few up to 0.1 m).
_MAP_DRIFT_M = 0.1


def _check_surface_grid(spec: str, bounds_m: np.ndarray, drift_m: float = _MAP_DRIFT_M, what: str = "it") -> None:
    """Refuse an object too large for the surface matcher's grid (:data:`maps.surface_field.MAX_CELLS`): its box
    ``bounds_m`` (2, 3) grown by ``drift_m`` - before any mapping - or its map's stored points' box after it."""
    from cansim.errors import InvalidInputError
    from maps.surface_field import MAX_CELLS, grid_cells

    cells = grid_cells(np.asarray(bounds_m) + [[-drift_m] * 3, [drift_m] * 3])
    if cells > MAX_CELLS:
        size = " x ".join(f"{x:.2f}" for x in np.ptp(bounds_m, axis=0))
        raise InvalidInputError(
            f"{object_label(spec)}: {what} spans {size} m: the surface matcher's grid over its map would need about "
            f"{cells:.3g} cells (at most "
            f"{MAX_CELLS:g}); give a smaller object (a cube up to about 0.8 m; --scale-to-m 0.35: the thesis objects' size), or run without the surface "
            "matcher (--matchers thesis)")


def _label(row: dict[str, Any]) -> str:
    return row["distance_bin"] or f"trajectory {row['presentation']}"


def accuracy(rows: Sequence[dict[str, Any]], novel: bool) -> dict[str, tuple[int, int]]:
    """(correct, runs) per presentation label, library objects or novel objects."""
    acc: dict[str, list[int]] = {}
    for r in rows:
        if bool(r["novel"]) == novel and r["library_size"] == min(x["library_size"] for x in rows):
            acc.setdefault(_label(r), []).append(bool(r["correct"]))
    return {k: (sum(v), len(v)) for k, v in acc.items()}


def confusion(rows: Sequence[dict[str, Any]], presented: Sequence[str] | None = None,
              decided: Sequence[str | None] | None = None) -> tuple[list[str], list[str | None], np.ndarray]:
    """Decisions per presented object: the counts of the confusion figure.

    Parameters
    ----------
    rows : sequence of dict
        Runs of ``recognition_runs.csv`` (``presented``, ``novel``, ``decision``: "" or None when no
        decision fired).
    presented : sequence of str, optional
        The rows' order (default: as the runs first present them).
    decided : sequence of str or None, optional
        The columns' order (default: the presented objects no run presents as novel, then None).

    Returns
    -------
    presented : list of str
        The presented objects (rows of ``counts``).
    decided : list of str or None
        The identities decided (columns): the presented library objects, then None, no decision
        (:data:`NO_DECISION` in the figure; an object may well be labelled "none").
    counts : ndarray, shape (len(presented), len(decided))
        Runs per presented object and decision.

    Raises
    ------
    InvalidInputError
        A run whose presented object or decision is not among the rows or columns given.
    """
    presented = list(dict.fromkeys(r["presented"] for r in rows)) if presented is None else list(presented)
    if decided is None:
        decided = [*(p for p in presented if not any(r["novel"] for r in rows if r["presented"] == p)), None]
    decided = list(decided)
    counts = np.zeros((len(presented), len(decided)))
    for r in rows:
        if r["presented"] not in presented or (r["decision"] or None) not in decided:
            raise InvalidInputError(f"a run presents {r['presented']!r} and decides {r['decision']!r}: not among the "
                                    f"rows {presented} and columns {decided} given")
        counts[presented.index(r["presented"]), decided.index(r["decision"] or None)] += 1
    return presented, decided, counts


def figures(rows: Sequence[dict[str, Any]], out: Path) -> list[Path]:
    """The confusion matrices, accuracy vs viewpoint distance and vs library size, and what the maps never felt.

    One set per matcher: the first matcher of the rows gets the plain file names, the
    others the suffix ``_<matcher>``.
    """
    matchers = list(dict.fromkeys(r["matcher"] for r in rows))
    files = []
    for i, m in enumerate(matchers):
        files += _figures([r for r in rows if r["matcher"] == m], out, "" if i == 0 else f"_{m}")
    return files


def _figures(rows: Sequence[dict[str, Any]], out: Path, suffix: str) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    small = min(r["library_size"] for r in rows)
    base = [r for r in rows if r["library_size"] == small]
    labels = list(dict.fromkeys(_label(r) for r in base))
    presented, decided, _ = confusion(base)  # one order of rows and columns for every panel
    files = []
    fig, axes = plt.subplots(1, len(labels), figsize=(4.2 * len(labels) + 1.5, 0.24 * len(presented) + 2.8), squeeze=False,
                             sharey=True, layout="constrained")  # one column of object names, not one over each neighbour
    for ax, lab in zip(axes[0], labels):
        m = confusion([r for r in base if _label(r) == lab], presented, decided)[2]
        m /= np.maximum(m.sum(axis=1, keepdims=True), 1)
        im = ax.imshow(m, vmin=0, vmax=1, cmap="Blues")
        label = object_labels(presented)
        ax.set_xticks(range(len(decided)), [NO_DECISION if d is None else label[d] for d in decided], rotation=90,
                      fontsize=6)
        ax.set_yticks(range(len(presented)), [label[p] for p in presented], fontsize=6)
        ax.set_xlabel("decided identity (IC >= 300)")
        ax.set_title(lab, fontsize=9)
    axes[0][0].set_ylabel("presented object (novel ones last)")
    fig.colorbar(im, ax=axes[0].tolist(), shrink=0.8, label="fraction of runs")
    fig.suptitle(f"Recognition decisions, library of {small} objects, matcher {rows[0]['matcher']}")
    files.append(out / f"recognition_confusion{suffix}.png")
    fig.savefig(files[-1], dpi=110, bbox_inches="tight")
    plt.close(fig)
    # accuracy vs viewpoint distance
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for novel, colour, what in ((False, "tab:blue", "library objects: correct identity"),
                                (True, "tab:orange", "novel objects: no decision")):
        acc = accuracy(rows, novel)
        xs, ys = [], []
        for r in base:
            if bool(r["novel"]) == novel:
                xs.append(r["median_distance_m"] * 100)
                ys.append(float(bool(r["correct"])))
        ax.scatter(xs, np.array(ys) + (0.02 if novel else -0.02), s=10, color=colour, alpha=0.4)
        for j, (lab, (c, n)) in enumerate(acc.items()):
            d = np.median([r["median_distance_m"] * 100 for r in base if _label(r) == lab and bool(r["novel"]) == novel])
            ax.plot(d, c / n, "o", ms=9, color=colour, mec="k")
            if not novel:
                ax.annotate(f"{lab}: {c}/{n}", (d, c / n), textcoords="offset points", xytext=(6, -12 + 10 * (j % 3)),
                            fontsize=7)  # staggered: conditions at the same distance do not overwrite each other
        ax.plot([], [], "o", color=colour, mec="k", label=f"{what} (share per presentation)")
    ax.axhline(0.9, color="0.5", ls=":", lw=1, label="issue 22 target (library objects)")
    ax.set_xlabel("median distance of the presentation's whisks to the nearest mapping pose (cm)")
    ax.set_ylabel("share of runs right")
    ax.set_ylim(-0.08, 1.08)
    ax.legend(fontsize=7, loc="center right")
    ax.set_title("Accuracy vs viewpoint distance (dots: single runs)")
    files.append(_saved(fig, out / f"recognition_accuracy_vs_distance{suffix}.png"))
    # accuracy vs library size (trajectory B)
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    sizes = sorted({r["library_size"] for r in rows})
    for novel, colour, what in ((False, "tab:blue", "library objects"), (True, "tab:orange", "novel objects")):
        ys = []
        for n in sizes:
            sel = [bool(r["correct"]) for r in rows if r["library_size"] == n and r["presentation"] == "B"
                   and bool(r["novel"]) == novel]
            ys.append(sum(sel) / len(sel) if sel else math.nan)
        ax.plot(sizes, ys, "o-", color=colour, label=what)
    ax.set_xlabel("library size (objects)")
    ax.set_ylabel("share of runs right (trajectory B)")
    ax.set_ylim(-0.05, 1.05)
    ax.set_xticks(sizes)
    ax.legend(fontsize=8)
    ax.set_title("Accuracy vs library size")
    files.append(_saved(fig, out / f"recognition_accuracy_vs_library{suffix}.png"))
    # what the own map never felt against the own impulses (library objects, every presentation)
    mapped = [r for r in base if not bool(r["novel"]) and r.get("unmapped_contact_fraction", "") != ""]
    if mapped:
        fig, ax = plt.subplots(figsize=(6.5, 4.2))
        for j, lab in enumerate(labels):
            colour = f"C{j}"
            for right, marker in ((True, "o"), (False, "x")):
                sel = [r for r in mapped if _label(r) == lab and bool(r["correct"]) == right]
                if sel:
                    ax.scatter([100 * float(r["unmapped_contact_fraction"]) for r in sel],
                               [int(r["impulses_own"]) / max(int(r["whisks"]), 1) for r in sel],
                               marker=marker, color=colour, s=28,
                               label=f"{lab}: {'correct' if right else 'missed'} ({len(sel)})")
        ax.set_xlabel("contacts where the own map felt nothing (%, at their true poses)")
        ax.set_ylabel("own impulses per whisk")
        ax.set_ylim(-0.05, 1.05)
        ax.legend(fontsize=7)
        ax.set_title("What the map never felt vs the own object's impulses")
        files.append(_saved(fig, out / f"recognition_unmapped{suffix}.png"))
    return files


def _saved(fig: Any, path: Path) -> Path:
    """``fig`` laid out, written to ``path`` (110 dpi) and closed; the path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


_MATCHER_LABEL = {"thesis": "thesis (Eq 5.5 region match)", "surface": "surface (maps.surface_match on the stored surfaces)"}


def summary(rows: Sequence[dict[str, Any]], elapsed_s: float, quick: bool, odometry_scale: float = 1.0) -> str:
    """The issue's acceptance figures and the thesis' Fig 5.17 findings, each held or not (one section per matcher);
    ``odometry_scale`` is the run's (:func:`run`'s), stated in each section's first line."""
    matchers = list(dict.fromkeys(r["matcher"] for r in rows))
    return "\n\n".join(_summary([r for r in rows if r["matcher"] == m], elapsed_s, quick, m, odometry_scale)
                       for m in matchers)


def _summary(rows: Sequence[dict[str, Any]], elapsed_s: float, quick: bool, matcher: str,
             odometry_scale: float = 1.0) -> str:
    lib = accuracy(rows, False)
    nov = accuracy(rows, True)
    small = min(r["library_size"] for r in rows)
    base = [r for r in rows if r["library_size"] == small and not r["novel"]]
    off = sum(1 for r in base if r["decision"] and r["decision"] != r["presented"])
    seeds = sorted({r["seed"] for r in rows})

    def share(d: dict[str, tuple[int, int]], key: str) -> str:
        c, n = d.get(key, (0, 0))
        return f"{c}/{n} ({100 * c / n:.0f} %)" if n else "not run"

    def held(d: dict[str, tuple[int, int]], key: str, target: float) -> str:
        c, n = d.get(key, (0, 0))
        return "HELD" if n and c / n >= target else "NOT HELD"

    lines = [f"Recognition benchmark ({'--quick' if quick else 'full'}): library of {small} object{'s' * (small != 1)}, "
             f"seeds {seeds}, "
             f"IC threshold {IC_THRESHOLD:g}, matcher {_MATCHER_LABEL.get(matcher, matcher)}, odometry noise "
             f"{odometry_scale:g} x Eq 6.4-6.11{' (the thesis)' if odometry_scale == 1 else ''}; {elapsed_s / 60:.1f} min "
             "(all matchers).", "",
             "Targets (issue 22's acceptance; library objects: the correct IC decision; novel objects: no decision):"]
    for key, target in (("trajectory A", 1.0), ("trajectory B", 0.9), ("vp 5-10 cm", 0.9)):
        lines.append(f"  {key:14s} correct {share(lib, key):14s} target {target:.0%}: {held(lib, key, target)}")
    for key in lib:
        if key not in ("trajectory A", "trajectory B", "vp 5-10 cm"):
            lines.append(f"  {key:14s} correct {share(lib, key)} (reported)")
    novel_all = (sum(c for c, _ in nov.values()), sum(n for _, n in nov.values()))
    held = "not measured (no novel object)" if not novel_all[1] else \
        "HELD" if novel_all[0] / novel_all[1] >= 0.95 else "NOT HELD"
    lines.append(f"  novel objects  no decision in {novel_all[0]}/{novel_all[1]} presentations target 95 %: {held}")
    taken: dict[str, list[str]] = {}
    for r in rows:  # which library object each decided novel presentation was taken for
        if r["novel"] and r["library_size"] == small and r["decision"]:
            taken.setdefault(object_label(r["presented"]), []).append(object_label(r["decision"]))
    for name, decided in taken.items():
        counts = {d: decided.count(d) for d in dict.fromkeys(decided)}
        lines.append(f"    the {name} (novel) was taken for " + ", ".join(f"the {d} {k}x" for d, k in counts.items()))
    if small == 1:
        lines.append("  Note: with one library object every decision names it; add objects for the figures to mean "
                     "anything.")
    lines.append(f"  off-diagonal decisions (a library object named as another; novel ones are counted above) "
                 f"{off}/{len(base)} target <= 5 %: "
                 f"{'HELD' if base and off / len(base) <= 0.05 else 'NOT HELD'}")
    cover = [r for r in base if r["presentation"] != "A" and r.get("unmapped_contact_fraction", "") != ""]
    if cover:
        def med(c: list[dict[str, Any]]) -> str:
            return f"{100 * float(np.median([float(r['unmapped_contact_fraction']) for r in c])):.0f} %" if c else "-"

        hit, miss = [r for r in cover if r["correct"]], [r for r in cover if not r["correct"]]
        lines.append(f"  contacts where the own map felt nothing (off trajectory A, median): correct runs {med(hit)} "
                     f"({len(hit)}), missed runs {med(miss)} ({len(miss)})")
    need = whisks_to_decide()
    short = sum(1 for r in rows if int(r["whisks"]) < need)
    if short:
        lines.append(f"  Warning: {short} of {len(rows)} runs had fewer whisks than any decision at IC {IC_THRESHOLD:g} "
                     f"needs ({need}, with an impulse at every whisk): they cannot be decided - give more --whisks.")
    seldom = sorted({object_label(r["presented"]) for r in rows
                     if int(r["whisks"]) and int(r["whisks_with_contact"]) < 0.5 * int(r["whisks"])})
    if seldom:
        lines.append(f"  Warning: seldom touched - under half the whisks of a presentation observed a region (3 contacts "
                     f"or more): {', '.join(seldom)}. Their maps and decisions say little: a flat or thin object passes "
                     "between the array's rows of whiskers (--roll-deg 0 whisks it rolled), a mesh in millimetres or "
                     "lying on its side is out of reach (--scale-to-m, --up-axis).")
    lines += ["", "Thesis Fig 5.17 findings:",
              f"  own map recognised along A (thesis: yes): {share(lib, 'trajectory A')}",
              f"  along B lower than A but still identified (thesis: yes): {share(lib, 'trajectory B')}",
              "  (the thesis' B runs scored lower confidences than A's and still named the object; a measured "
              "share well below A's means the region match recognises visited poses, not the surface)"]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Command line (``cansim study recognition``)."""
    ap = CommandParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="12 objects, 1 seed, trajectories A and B and the 5-10 cm viewpoints")
    ap.add_argument("--out", type=Path, default=Path.cwd(), help="output folder (default: working directory)")
    ap.add_argument("--objects", nargs="+", metavar="NAME_OR_MESH", help="library objects (default: the 12-object library)")
    ap.add_argument("--novel", nargs="*", metavar="NAME_OR_MESH",
                    help="novel objects (default: three held-out shapes; none after the flag: no novel object)")
    add_mesh_options(ap, per_file=True)
    ap.add_argument("--seeds", type=int, default=None,
                    help="how many seeds: --seed, --seed + 1, ... (default 3, quick 1)")
    ap.add_argument("--seed", type=int, default=0,
                    help="the first seed (default 0); the maps' T_pfh / T_sda are calibrated on it (--calibration)")
    ap.add_argument("--whisks", type=int, default=200, help="least whisks per presentation (default 200)")
    ap.add_argument("--map-loops", type=int, default=2, help="loops of trajectory A per map (default 2)")
    ap.add_argument("--matchers", "--matcher", nargs="+", choices=MATCHERS, default=list(DEFAULT_MATCHERS),
                    help=f"matchers deciding every presentation (default: {' '.join(DEFAULT_MATCHERS)})")
    ap.add_argument("--odometry-noise", type=float, default=1.0, metavar="SCALE",
                    help="odometry noise of maps and presentations as a multiple of Eq 6.4-6.11 (default 1: the thesis'); "
                         "the surface matcher and the maps' pose graphs assume it, at least 0.25 of it")
    ap.add_argument("--calibration", choices=CALIBRATIONS, default="first-seed",
                    help="T_pfh / T_sda of the maps: first-seed (default; the 0.75 quantile on the run's first seed) or "
                         f"pooled (the {CALIBRATION_QUANTILE:g} quantile over {CALIBRATION_SEEDS} calibration seeds that "
                         "are not study seeds: the same thresholds whatever --seeds; tried, not better, module Status)")
    ap.add_argument("--reach-contacts", type=int, default=REACH_CONTACTS, metavar="K",
                    help=f"whiskers every mapping and presentation pose reaches for (default {REACH_CONTACTS}; "
                         "0: the fixed standoff of the Ch.5 study)")
    ap.add_argument("--roll-deg", type=float, default=None, metavar="DEG",
                    help="the array's roll about its axis on every trajectory, degrees (default: per object, the "
                         "thesis' 90 unless 0 reaches the object clearly more often: flat tori, bowls)")
    ap.add_argument("--workers", type=int, default=2, help="processes mapping and presenting in parallel (default 2)")
    ap.add_argument("--no-progress", action="store_true", help="no progress bars on stderr")
    a = ap.parse_args(None if argv is None else list(argv))
    for name in ("whisks", "map_loops", "workers"):
        if getattr(a, name) < 1:
            ap.error(f"--{name.replace('_', '-')} must be >= 1")
    if a.seeds is not None and a.seeds < 1:
        ap.error("--seeds must be >= 1")
    if a.seed < 0:
        ap.error(f"--seed must be >= 0, got {a.seed}")
    if not 0.0 <= a.odometry_noise <= 10.0:
        ap.error("--odometry-noise must be in [0, 10]")
    from whisker_io.array.geometry import THESIS_POSITIONS_MM

    whiskers = len(THESIS_POSITIONS_MM)
    if not 0 <= a.reach_contacts <= whiskers:
        ap.error(f"--reach-contacts must be in [0, {whiskers}] (the thesis array's whiskers)")
    if a.roll_deg is not None and not (math.isfinite(a.roll_deg) and -360.0 <= a.roll_deg <= 360.0):
        ap.error("--roll-deg must be a number of degrees in [-360, 360]")
    t0 = time.perf_counter()
    seeds = range(a.seed, a.seed + (a.seeds if a.seeds is not None else (1 if a.quick else 3)))
    bins = ("vp 5-10 cm",) if a.quick else None
    sizes = (12,) if a.quick or a.objects else (12, 25, 50)
    rows = run(a.out, a.objects, a.novel, library_sizes=sizes if not a.objects else (len(a.objects),), seeds=seeds,
               bins=bins, map_loops=a.map_loops, whisks=a.whisks, workers=a.workers, progress=not a.no_progress,
               matchers=a.matchers, odometry_scale=a.odometry_noise, calibration=a.calibration,
               reach_contacts=a.reach_contacts, roll_deg=a.roll_deg, scale_to_m=a.scale_to_m, up_axis=a.up_axis)
    files = figures(rows, a.out)
    text = summary(rows, time.perf_counter() - t0, a.quick, a.odometry_noise)
    (a.out / "recognition_summary.txt").write_text(text + "\n")
    print(text)
    print("Wrote " + ", ".join(f.name for f in [a.out / "recognition_runs.csv", *files, a.out / "recognition_summary.txt"])
          + f" in {a.out.resolve()}.")
    return 0


if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "recognition"))
