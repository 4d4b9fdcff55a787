"""Actors: every subsystem of the runtime, exchanging typed messages.

The actor base, the messages and the actors themselves arrive with the
runtime issue; the package exists so that the layout is fixed from the start.
"""
