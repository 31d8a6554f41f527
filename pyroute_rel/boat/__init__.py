"""The boat: polars (speed over wind angle and speed), tacks and gybes, and holding a course in a current."""
