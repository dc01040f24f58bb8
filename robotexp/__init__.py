"""robotexp: mobile-robot exploration experiments, the same on a simulator and on real robots.

Importing this package is cheap: pybullet, numba, lupa and pymavlink load only in the modules
that need them.
"""

__version__ = "0.1.0"
