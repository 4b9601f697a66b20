# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Joint controllers (PP-NFTSMC-ESO and baselines): ROS-free laws and the controller node."""
