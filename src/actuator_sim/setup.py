# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Set-up of the ament_python package actuator_sim."""

import os
from glob import glob

from setuptools import find_packages, setup

package_name = 'actuator_sim'


def share_files(folder, pattern):
    """Install folder/pattern into share/<package>/folder when the folder has such files."""
    files = sorted(glob(os.path.join(folder, pattern)))
    return [(os.path.join('share', package_name, folder), files)] if files else []


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        *share_files('launch', '*.launch.py'),
        *share_files('config', '*.yaml'),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Actuator control team',
    maintainer_email='actuator@example.com',
    description='ROS-free closed loop, scenarios, offline simulation and stability analysis.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'offline_sim = actuator_sim.offline:main',
            'stability_check = actuator_sim.stability:main',
            'late_commands = actuator_sim.late_commands:main',
            'late_answers = actuator_sim.late_answers:main',
        ],
    },
)
