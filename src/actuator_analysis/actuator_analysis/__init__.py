# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Offline analysis of recorded runs: load a bag, the paper's metrics, the table, the figures."""
