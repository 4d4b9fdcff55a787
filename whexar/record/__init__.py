"""Recordings: every message and every byte of a run in one MCAP file, and reading them back.

May import: :mod:`whexar.testing`, :mod:`whexar.actors` and everything below them;
never :mod:`whexar.sim`, :mod:`whexar.bench` or :mod:`whexar.cli`.
"""
