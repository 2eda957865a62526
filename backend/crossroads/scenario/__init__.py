"""The scenario, the user's main noun: its format (spec.py) and its checks against a built network."""
