"""The ``pyroute-rel`` command line: ``route`` and ``failure`` (:mod:`.main`), ``gci`` (:mod:`.gci`)."""

from __future__ import annotations

from pyroute_rel.cli.main import build_parser, main

__all__ = ["main", "build_parser"]
