# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Set-up of the ament_python package actuator_studies."""

from setuptools import find_packages, setup

package_name = 'actuator_studies'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', ['config/pp_nftsmc_eso_designed.yaml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Actuator control team',
    maintainer_email='actuator@example.com',
    description='Envelope sweeps, Monte Carlo studies and robust gain design over the offline '
    'closed loop.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'sweep = actuator_studies.cli:sweep_main',
            'sweep-bench = actuator_studies.cli:bench_main',
            'design_gains = actuator_studies.cli:design_main',
            'sweep-compare = actuator_studies.cli:compare_main',
        ],
    },
)
