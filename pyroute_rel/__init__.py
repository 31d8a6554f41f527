"""pyroute_rel: reliability-informed routing for autonomous sailing craft."""

from __future__ import annotations

__version__ = "0.1.0"
