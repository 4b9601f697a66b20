# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""CiA 402 (CANopen drive profile) hardware driver for the joint actuator.

And a simulated drive.
"""
