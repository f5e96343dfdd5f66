"""Benchmarks of whisker signals (issue 6 part B): contact detection for one array cycle
(18 modules x 2000 samples, target <= 5 ms), beam-model signal synthesis for one array
whisk, contact features for 18 contacts, and a whole simulated array whisk against the
Kettle (sweep + signals).

Run: ``python -m pytest bench/test_bench_whisker_signals.py --benchmark-only``
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from whisker_io.contact.detection import detect_contacts
from whisker_io.contact.features import contact_features
from whisker_io.array.control import OpenLoop, RetractAtMax, WhiskPattern
from whisker_io.sim.objects import make_object
from whisker_io.sim.signals import WhiskContact, simulate_whisk_cycle
from whisker_io.sim.simulator import ArraySimulator
from whisker_io.sim.sweep import MeshTarget

LENGTHS = np.repeat([[0.06, 0.1, 0.16]], 6, axis=0).ravel()


def _array_contacts() -> list[WhiskContact | None]:
    """12 of 18 whiskers in contact at varied angles / radial distances, 6 free."""
    rng = np.random.default_rng(0)
    out: list[WhiskContact | None] = []
    for i, L in enumerate(LENGTHS):
        if i % 3 == 2 and i > 6:
            out.append(None)
            continue
        out.append(WhiskContact(math.radians(rng.uniform(-30, 30)), rng.uniform(0.3, 0.8) * L, L))
    return out


def test_detect_contacts_array_cycle_18x2000(benchmark):
    recs, _ = simulate_whisk_cycle(_array_contacts(), OpenLoop(WhiskPattern(1.0)), seed=1)
    dets = benchmark(detect_contacts, recs)
    assert sum(d is not None for d in dets) >= 10


def test_contact_features_18_contacts(benchmark):
    recs, _ = simulate_whisk_cycle(_array_contacts(), OpenLoop(WhiskPattern(1.0)), seed=1)
    dets = detect_contacts(recs)
    keep = [i for i, d in enumerate(dets) if d is not None]
    args = ([recs[i] for i in keep], [dets[i] for i in keep], LENGTHS[keep])
    F = benchmark(contact_features, *args)
    assert F.shape == (len(keep), 7)


def test_synthesize_array_whisk_18x2000_retract_at_max(benchmark):
    contacts = _array_contacts()
    ctrl = RetractAtMax(WhiskPattern(1.0))
    recs, _ = benchmark(simulate_whisk_cycle, contacts, ctrl, None, 3)
    assert len(recs) == 18


def test_simulated_array_whisk_kettle_sweep_plus_signals(benchmark):
    R = Rotation.random(random_state=262).as_matrix()
    pose = np.eye(4)
    pose[:3, :3] = R
    pose[:3, 3] = np.array([0.0, 0.0, 0.15]) - R[:, 1] * 0.30
    target = MeshTarget(make_object("kettle"))
    sim = ArraySimulator(seed=0)
    res = benchmark(sim.whisk, target, pose)
    assert sum(sc is not None for sc in res.sweep_contacts) >= 6
