# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Set-up of an ament_python package of the suite: its metadata is in setup.cfg."""

from setuptools import setup

setup()
