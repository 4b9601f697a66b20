# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Process supervisor and runner, main job, benchmark and middleware-floor nodes."""
