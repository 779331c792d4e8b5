"""delaytrack: control of Euler-Lagrange systems under unknown input delay."""
