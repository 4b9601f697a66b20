# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The Foxglove live view of the running loop and its layout."""
