"""Rate and spiking attractors driven by recorded rat trajectories (ratinabox's data): a thin script over :mod:`cansim.studies.rat_trajectories` (same as ``cansim study rat``; ``--help`` lists the options)."""
from cansim.studies.rat_trajectories import main
from whisker_io.command_line import run_command

if __name__ == "__main__":
    raise SystemExit(run_command(main, "rat_trajectories"))
