"""Analyses over many objects: feature tables, trajectories, classification, baselines.

Headless: never imports Qt or napari.
"""
