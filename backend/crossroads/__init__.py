"""Crossroads: a scenario studio and evaluator for driving policies at signalized intersections.

Implements integrated decision and control (IDC) with the general static path planner and
adversarial policy gradient (APG) of Ren et al., "Improve Generalization of Driving Policy at
Signalized Intersections with Adversarial Learning".
"""

__version__ = "0.1.0"
