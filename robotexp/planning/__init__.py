"""Planning, the explorers' toolkit (public): grid planners (grid_planner.py), the shared `PathFollower`
(follower.py), frontier targets and plan costs (targets.py), harmonic potentials (harmonic.py), Santos's
objective (objective.py) and metaheuristics (metaheuristics.py). Import the modules."""
