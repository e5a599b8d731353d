"""The ``--dt-s`` and ``--substeps`` options of the task examples: a
simulation step and steps per env step other than the task's own."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds ``--dt-s`` and ``--substeps`` to ``parser``."""
    parser.add_argument("--dt-s", type=float, help="simulation step, s (default: the task's, 1/90)")
    parser.add_argument("--substeps", type=int, help="simulation steps an env step (default: the task's, 3)")


def kwargs(args: argparse.Namespace) -> dict:
    """The ``gym.make`` keywords of the options given: ``dt_s``, ``substeps``."""
    return {k: v for k, v in (("dt_s", args.dt_s), ("substeps", args.substeps)) if v is not None}
