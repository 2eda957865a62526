"""Searching scenario space for a policy's failures, and keeping them as regression scenarios.

``space`` reads a space file (which scenario parameters may move, and how far); ``objective``
grades an episode by how close it came to failing; ``shrink`` moves a failure back towards the
nominal scenario; ``engine`` runs a search (optuna's sampler, episodes as stored batches through
the evaluation executors), ``records`` keeps it in the results store, ``collection`` writes the
failures as scenario files and ``report`` plots what drives them.
"""
