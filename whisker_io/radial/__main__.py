"""Command line: train every radial-distance model once, evaluate saved models once.

::

    python -m whisker_io.radial train --models models/ [--quick] [--seed 0]
    python -m whisker_io.radial evaluate --models models/ [--out .] [--quick] [--seed 0]

``train`` simulates the training set (Sec 4.1.2.1), fits the 12 Table 4.1 models and
the two baselines with hyper-parameters chosen by cross-validation on the training
set only, and saves each as ``<label>.skops`` (see :mod:`whisker_io.radial.persistence`).
``evaluate`` loads every ``*.skops`` in the folder (refusing files whose feature list,
format or library versions do not match), simulates the validation set (Sec 4.1.2.2)
and writes ``radial_results.csv`` for the contacts on unseen whisker lengths.
``--quick`` uses the reduced data sets and search grids (seconds instead of minutes).
The full study with figures is ``examples/radial_distance_study.py``.

The MLP search stops L-BFGS at its iteration bound, as the thesis' bounded search
does, so scikit-learn warns that it did not converge for many candidate fits; those
warnings are counted and reported in one line instead of one line each.

Exit status
-----------
0
    Success.
1
    The run failed: a model file is corrupt, untrusted or does not match this version,
    or the data are invalid (any :class:`~whisker_io.errors.CansimError`); the message
    says which file and what to do.
2
    Usage error: bad command line (argparse), or ``--models`` names a folder that holds
    no ``*.skops`` models (for ``evaluate``) or is not a folder.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from functools import partial
from pathlib import Path

from whisker_io.command_line import CommandParser
from whisker_io.radial.datasets import TrainingSetParams, ValidationSetParams, make_training_set, make_validation_set
from whisker_io.errors import CansimError
from whisker_io.radial.evaluation import evaluate_models, write_results_csv
from whisker_io.radial.models import SearchParams, train_models
from whisker_io.radial.persistence import load_model, save_model
from whisker_io.radial.pipeline import dataset_contact_points


def _train(args: argparse.Namespace) -> int:
    if args.models.exists() and not args.models.is_dir():
        print(f"--models {args.models} exists and is not a folder", file=sys.stderr)
        return 2
    tp, settings = TrainingSetParams(seed=args.seed), SearchParams(seed=args.seed)
    if args.quick:
        tp, settings = tp.reduced(), settings.quick()
    train = make_training_set(tp, progress=True)
    from sklearn.exceptions import ConvergenceWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        models = train_models(train, settings=settings, progress=True)
    n_conv = 0
    for w in caught:  # count the expected ones, pass every other warning on unchanged
        if issubclass(w.category, ConvergenceWarning):
            n_conv += 1
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if n_conv:
        print(
            f"note: {n_conv} candidate MLP fits stopped at the iteration bound before converging "
            "(expected: the search is bounded, as in the thesis); the selected models are saved",
            file=sys.stderr,
        )
    args.models.mkdir(parents=True, exist_ok=True)
    for label, model in models.items():
        save_model(model, args.models / f"{label}.skops")
    print(f"trained {len(models)} models on {len(train)} contacts; saved to {args.models}/")
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    if not args.models.is_dir():
        print(f"--models {args.models} is not a folder; run 'python -m whisker_io.radial train --models DIR' first",
              file=sys.stderr)
        return 2
    files = sorted(args.models.glob("*.skops"))
    if not files:
        print(f"no *.skops model files in {args.models}; run 'python -m whisker_io.radial train' first", file=sys.stderr)
        return 2
    models = {f.stem: load_model(f) for f in files}
    vp = ValidationSetParams(seed=args.seed + 1)
    if args.quick:
        vp = vp.reduced()
    val = make_validation_set(vp, progress=True)
    scores = evaluate_models(
        models, val.data, keep=val.unseen, reconstruct=partial(dataset_contact_points, val.array), mesh=val.mesh,
        seed=args.seed,
    )
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "radial_results.csv"
    write_results_csv(scores, path)
    for s in sorted(scores, key=lambda s: s.median_abs_error):
        print(f"{s.model:8s} {s.features:22s} median |error| {s.median_abs_error:.4f} of WL  KS p vs tip {s.ks_p_vs_tip:.1e}")
    print(f"wrote {path}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = CommandParser(prog="python -m whisker_io.radial", description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    for name, help_ in (("train", "train and save every model"), ("evaluate", "evaluate saved models")):
        p = sub.add_parser(name, help=help_)
        p.add_argument("--models", type=Path, required=True, help="folder of <label>.skops model files")
        p.add_argument("--quick", action="store_true", help="reduced data sets and search grids")
        p.add_argument("--seed", type=int, default=0)
        if name == "evaluate":
            p.add_argument("--out", type=Path, default=Path.cwd(), help="where radial_results.csv goes")
    args = ap.parse_args(argv)
    try:
        return _train(args) if args.command == "train" else _evaluate(args)
    except CansimError as exc:  # the status cansim gives it (3: a corrupt model file; 6: a missing extra)
        from whisker_io.command_line import report_error

        return report_error(exc, ap.prog)


if __name__ == "__main__":
    raise SystemExit(main())
