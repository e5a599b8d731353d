"""The options the task examples share: ``--dt-s`` and ``--substeps`` (a
simulation step and steps per env step other than the task's own),
``--set`` (changes to the task's scene, as ``cloth run --set`` takes
them) and ``--start-states`` (episodes drawn from that many start
states)."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds ``--dt-s``, ``--substeps``, ``--set`` and ``--start-states`` to
    ``parser``."""
    parser.add_argument("--dt-s", type=float, help="simulation step, s (default: the task's, 1/90)")
    parser.add_argument("--substeps", type=int, help="simulation steps an env step (default: the task's, 3)")
    parser.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="a change to the task's scene, e.g. solver.contacts.max_passes=3 (repeatable)",
    )
    parser.add_argument(
        "--start-states", type=int, help="draw each episode's start from this many start states (default: none)"
    )


def kwargs(args: argparse.Namespace) -> dict:
    """The ``gym.make`` keywords of the options given: ``dt_s``,
    ``substeps``, ``overrides``, ``start_states``."""
    given = (
        ("dt_s", args.dt_s),
        ("substeps", args.substeps),
        ("overrides", args.set),
        ("start_states", args.start_states),
    )
    return {k: v for k, v in given if v is not None}
