"""Experiments reproducing the paper's figures and tables, and comparisons with peers."""
