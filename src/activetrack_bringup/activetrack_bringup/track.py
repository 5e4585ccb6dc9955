"""``activetrack track DETECTIONS --config CONFIG``: the tracker on recorded detections
(docs/track-your-data.md): a CSV or JSON file (:mod:`activetrack.tracking.detections`) or a bag
of ``Scan`` messages (:mod:`activetrack_bringup.track_bag`), with a tracker configuration or a
scenario file; ``--run`` seeds as ``run`` and ``batch`` do, so a run's scans with its scenario
and run index give the run's tracks bit for bit. A bad input is one ``error:`` line, exit 2,
before anything is tracked.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from activetrack_bringup import cli_types

__all__ = ["add_track_parser"]


def add_track_parser(sub) -> None:
    """``activetrack track DETECTIONS --config CONFIG [--truth T] [--run R] [--out DIR]
    [--json PATH] [--csv PATH] [--skip-damaged]``."""
    track = sub.add_parser(
        "track", help="track recorded detections (CSV, JSON or a bag) with a tracker configuration"
    )
    track.add_argument(
        "detections", help="a .csv or .json file of detections, or a bag of Scan messages"
    )
    track.add_argument(
        "--config", required=True, help="tracker configuration (YAML), or a scenario file"
    )
    track.add_argument(
        "--truth",
        help="targets' truth: a .csv or .json file, or a bag with ground_truth (default: the "
        "detections bag's own, if it has one)",
    )
    track.add_argument("--run", type=cli_types.run_index, help="Monte Carlo run index (seeding)")
    track.add_argument(
        "--out",
        type=cli_types.output_folder,
        help="output folder (default runs/<name>-<timestamp>; must not exist)",
    )
    track.add_argument(
        "--json",
        type=cli_types.output_file,
        help="also write the tracks (and GOSPA) to this JSON file",
    )
    track.add_argument(
        "--csv", type=cli_types.output_file, help="also write the tracks to this CSV file"
    )
    track.add_argument(
        "--skip-damaged",
        action="store_true",
        help="track the epochs a truncated bag holds (default: refuse a damaged bag)",
    )
    track.set_defaults(func=cmd_track)


def _is_bag(path: Path) -> bool:
    return path.is_dir() or path.suffix.lower() == ".mcap"


def _inputs(args: argparse.Namespace, config, sensors):
    """The detections and the truth (or None)."""
    from activetrack.tracking.detections import read_detections, read_truth
    from activetrack_bringup.track_bag import read_bag, read_bag_truth

    source = Path(args.detections)
    truth = None
    if _is_bag(source):
        detections, truth = read_bag(source, config, sensors, args.skip_damaged)
    else:
        if not source.exists():
            raise ValueError(f"{source}: no such file")
        detections = read_detections(source, sensors, config.dt, config.steps)
    if args.truth:
        path = Path(args.truth)
        if not path.exists():
            raise ValueError(f"{path}: no such file (--truth)")
        if _is_bag(path):
            truth = read_bag_truth(path, config, args.skip_damaged)
        else:
            truth = read_truth(path, config.dt)
    return detections, truth


def _write_outputs(args: argparse.Namespace, folder: Path, config, sensors, detections, run, truth):
    """The output folder and the extra copies; the warnings."""
    from activetrack.tracking.track_files import write_tracks_csv, write_tracks_json
    from activetrack_bringup.track_bag import write_track_bag

    extra = {"config": config.name, "epochs": run.epochs, "source": str(args.detections)}
    if run.gospa is not None:
        extra["gospa"] = run.gospa.to_json()
    folder.mkdir(parents=True, exist_ok=True)
    warnings = write_track_bag(folder / "bag", config, sensors, detections, run, truth)
    copies = [(folder / "tracks.csv", folder / "tracks.json"), (args.csv, args.json)]
    for csv_path, json_path in copies:  # the folder's, and --csv and --json if given
        for path in (csv_path, json_path):
            if path:
                Path(path).parent.mkdir(parents=True, exist_ok=True)
        if csv_path:
            write_tracks_csv(csv_path, run.track_sets)
        if json_path:
            write_tracks_json(json_path, run.track_sets, **extra)
    if run.gospa is not None:
        with (folder / "gospa.csv").open("w", newline="") as f:
            out = csv.writer(f)
            out.writerow(["epoch", "gospa", "localisation", "missed", "false"])
            g = run.gospa
            for row in zip(g.epochs, g.gospa, g.localisation, g.missed, g.false, strict=True):
                out.writerow([int(row[0]), repr(float(row[1])), repr(float(row[2])), *row[3:]])
    return warnings


def _summary(args: argparse.Namespace, config, detections, run, folder: Path) -> None:
    last = run.track_sets[-1]
    started = max((t.track_id for ts in run.track_sets for t in ts.tracks), default=0)
    association = "known" if config.known_association else "jpda"
    print(
        f"tracked {args.detections}: {run.epochs} epochs, {detections.count} scans, "
        f"{detections.detection_count} detections ({config.name}: {config.tracker.filter}, "
        f"association {association})"
    )
    print(
        f"  tracks     {len(last.confirmed)} confirmed of {len(last.tracks)} at epoch "
        f"{last.epoch}; {started} started"
    )
    if run.gospa is not None:
        print(f"  GOSPA      {run.gospa.mean:9.2f} m (time-averaged over epochs 1..{run.epochs})")
    print(f"  folder     {folder}")
    for path in (args.csv, args.json):
        if path:
            print(f"  tracks     {path}")


def cmd_track(args: argparse.Namespace) -> int:
    from activetrack.closed_loop.components import scene_sensors
    from activetrack.closed_loop.recorded import track_detections
    from activetrack.scenarios import load_tracking
    from activetrack_bringup.run_folder import run_dir_for

    try:
        config = load_tracking(args.config)
        folder = run_dir_for(config.name, args.out)
        if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
            raise ValueError(f"{folder} exists already: write into a new folder (--out)")
        sensors = scene_sensors(config)
        detections, truth = _inputs(args, config, sensors)
        run = track_detections(config, detections, truth, args.run)
        warnings = _write_outputs(args, folder, config, sensors, detections, run, truth)
    except (ValueError, OSError) as exc:  # ScenarioError, DataFileError, BagError
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for line in warnings:
        print(f"warning: {line}", file=sys.stderr)
    _summary(args, config, detections, run, folder)
    return 0
