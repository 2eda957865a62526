"""The policy a user names: its reference (ref.py, one grammar) and its identity (identity.py)."""
