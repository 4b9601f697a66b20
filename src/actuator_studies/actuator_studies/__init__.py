"""Envelope sweeps, Monte Carlo studies and robust gain design over the offline closed loop."""
