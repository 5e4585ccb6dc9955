"""Experiment runners reproducing the papers' tables and figures."""
