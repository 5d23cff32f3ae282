"""Launching runs: processes, run directories, metrics files, plots and the live view."""
