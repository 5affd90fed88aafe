"""
ament_python package definition for mmg_tuner.

Executables are console scripts installed into lib/mmg_tuner (see setup.cfg) so that
`ros2 run mmg_tuner <exe>` finds them on a ROS 2 install.
"""
from glob import glob

from setuptools import find_packages, setup

package_name = 'mmg_tuner'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench']),
    # PEP 561: the package's inline annotations are for its users' type checkers
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        # real KVLCC2 free-running data (SIMMAN 2008, MARIN) used by the checks and examples
        ('share/' + package_name + '/data/kvlcc2_simman2008_marin',
         glob('data/kvlcc2_simman2008_marin/*')),
        # real Esso Osaka 3 m pond data (FRT-DS-ESSO, CC BY-NC-SA 4.0: LICENSE kept beside it)
        ('share/' + package_name + '/data/esso_osaka_frt',
         glob('data/esso_osaka_frt/LICENSE') + glob('data/esso_osaka_frt/README.md')),
    ] + [('share/' + package_name + '/data/esso_osaka_frt/' + kind,
          glob('data/esso_osaka_frt/' + kind + '/*.csv'))
         for kind in ('berthing', 'random', 'turning', 'zigzag')] + [
        # seven more runs of the same data set, the test set of bench/esso_fresh.py
        ('share/' + package_name + '/data/esso_osaka_frt_extra',
         glob('data/esso_osaka_frt_extra/LICENSE') + glob('data/esso_osaka_frt_extra/README.md'))
    ] + [('share/' + package_name + '/data/esso_osaka_frt_extra/' + kind,
          glob('data/esso_osaka_frt_extra/' + kind + '/*.csv'))
         for kind in ('turning', 'zigzag')],
    install_requires=['setuptools', 'numpy', 'pyyaml', 'numba', 'cmaes', 'rosbags', 'mcap'],
    zip_safe=False,
    maintainer='mmg_tuner developers',
    maintainer_email='dev@mmg-tuner.invalid',
    description='MMG manoeuvring model fine-tuning, diagnosis and ROS 2 simulation',
    license='Apache-2.0',
    extras_require={'test': ['pytest', 'hypothesis']},
    entry_points={
        'console_scripts': [
            'simulate = mmg_tuner.cli.simulate:main',
            'generate = mmg_tuner.cli.generate:main',
            'inspect = mmg_tuner.cli.inspect:main',
            'tune = mmg_tuner.cli.tune:main',
            'diagnose = mmg_tuner.cli.diagnose:main',
            'evaluate = mmg_tuner.cli.evaluate:main',
            'fleet = mmg_tuner.cli.fleet:main',
            'precompile = mmg_tuner.cli.precompile:main',
            'export = mmg_tuner.cli.export:main',
            'sim_node = mmg_tuner.ros.sim_node:main',
            'replay_node = mmg_tuner.ros.replay_node:main',
        ],
    },
)
