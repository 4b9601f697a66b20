# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Envelope sweeps, Monte Carlo studies and robust gain design over the offline closed loop."""
