"""Analysis of tracks and routes: evaluating any track, Monte Carlo, ensembles and their members, track similarity."""
