"""Models fitted to measured rows: work-counter cost models and their predictions for other
devices (:mod:`.cost`), scaling laws of error and cost against resolution and scene size
(:mod:`.scaling`).
"""
