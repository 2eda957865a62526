"""Intersections built: the specs (spec.py), their SUMO nets by netconvert (build.py), the catalogue
of named intersections (catalogue.py), and a name or a net file resolved to a junction (resolve.py)."""
