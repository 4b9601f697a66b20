# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Bring-up: the run description, the runner, the loop container and the main job."""
