"""The boat: polars (speed over wind angle and speed), sailing an arc through time-varying weather (the march),
tacks and gybes, and holding a course in a current."""
