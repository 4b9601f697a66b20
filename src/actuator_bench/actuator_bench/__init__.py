# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Benchmarks and probes: the closed-loop benchmark, middleware and host floors, callback cost."""
