"""Hokuyo URG/UTM laser driver: SCIP 2.0 over USB-ACM or TCP (work in progress)."""
