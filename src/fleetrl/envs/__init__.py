"""Cyber environments: Gymnasium envs over a device link, with the paper's reward and episode cap."""
