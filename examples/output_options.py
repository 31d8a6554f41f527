"""The output options the example scripts share: ``--out DIR`` or ``--figures``, and the folder they choose.

The scripts import this module from their own folder (``python examples/<script>.py`` puts ``examples/`` on
``sys.path``). They write to ``examples/output/`` (git ignores it) unless given ``--out``; ``--figures``
refreshes the committed figures in ``examples/figures/`` that the README shows.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def add_output_options(ap: argparse.ArgumentParser) -> None:
    """Add ``--out`` and ``--figures`` to an example's argument parser."""
    ap.add_argument("--out", help="output folder (default: examples/output/, which git ignores)")
    ap.add_argument(
        "--figures",
        action="store_true",
        help="write into examples/figures/ instead: refreshes the committed figures the README shows",
    )


def output_folder(ap: argparse.ArgumentParser, args: argparse.Namespace) -> Path:
    """The folder to write into: --out, examples/figures/ with --figures, else examples/output/ (never both)."""
    if args.figures and args.out is not None:
        print(f"{ap.prog}: error: give --out or --figures, not both", file=sys.stderr)
        raise SystemExit(2)
    out = HERE / "figures" if args.figures else Path(args.out) if args.out is not None else HERE / "output"
    out.mkdir(parents=True, exist_ok=True)
    return out
