"""
Build the tf2_msgs message package (TFMessage only) into this Python environment.

tf2_msgs has no wheel on PyPI, but the ROS 2 Jazzy rosidl generator wheels and the headers and
libraries of geometry_msgs are installed with rclpy. This runs the same generators colcon
would (rosidl_generator_c/py, rosidl_typesupport_c/introspection_c/fastrtps_c) on the one
message the simulator needs, compiles the results with gcc/g++ and installs them where the
wheels put theirs (``<prefix>/lib``, ``site-packages/tf2_msgs``, ``share/tf2_msgs``), so that
``from tf2_msgs.msg import TFMessage`` works with rclpy and interoperates with a real Jazzy
system (same definition, same type hash).

Idempotent: does nothing when tf2_msgs is already importable (a real ROS install, or an
earlier run). Run with the venv's python: ``.venv/bin/python scripts/build_tf2_msgs.py``.
"""
from __future__ import annotations

import contextlib
import importlib.util
import io
import os
from pathlib import Path
import shutil
import subprocess
import sys
import sysconfig
import tempfile

PKG = 'tf2_msgs'
# tf2_msgs/msg/TFMessage.msg of ROS 2 Jazzy (geometry2 0.36), verbatim
TF_MESSAGE_MSG = 'geometry_msgs/TransformStamped[] transforms\n'
TYPESUPPORTS = ('c', 'introspection_c', 'fastrtps_c')


def run(cmd: list[str], cwd: Path) -> None:
    res = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f'build_tf2_msgs: {" ".join(cmd[:3])} ... failed:\n{res.stdout}{res.stderr}')


def generate(src: Path, gen: Path) -> None:
    """
    Run the rosidl generators directly.

    The rosidl generators, called directly (the ``rosidl generate`` CLI refuses the duplicate entry
    points the wheels register).
    """
    # the generators find their templates through the ament index of this prefix
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    os.environ['AMENT_PREFIX_PATH'] = os.pathsep.join([sys.prefix] + prefixes)
    from rosidl_generator_c.cli import GenerateC
    from rosidl_generator_py.cli import GeneratePython
    from rosidl_typesupport_c.cli import GenerateCTypesupport
    from rosidl_typesupport_fastrtps_c.cli import GenerateFastRTPSCTypesupport
    from rosidl_typesupport_introspection_c.cli import GenerateIntrospectionCTypesupport
    files = [f'{src}:msg/TFMessage.msg']
    include = [str(Path(sys.prefix) / 'share')]
    chatter = io.StringIO()  # the generators print every file; shown only on failure
    try:
        with contextlib.redirect_stdout(chatter), contextlib.redirect_stderr(chatter):
            for name, cls in (('c', GenerateC), ('py', GeneratePython),
                              ('ts_c', GenerateCTypesupport),
                              ('ts_introspection_c', GenerateIntrospectionCTypesupport),
                              ('ts_fastrtps_c', GenerateFastRTPSCTypesupport)):
                cls(name).generate(PKG, files, include, gen / name)
    except Exception:
        print(chatter.getvalue(), file=sys.stderr)
        raise


def build(gen: Path, out: Path) -> None:
    prefix = Path(sys.prefix)
    inc = out / 'include' / PKG
    for part in ('c', 'ts_introspection_c', 'ts_fastrtps_c'):
        shutil.copytree(gen / part / 'msg', inc / 'msg', dirs_exist_ok=True)
    import numpy
    flags = ['-shared', '-fPIC', '-O2', f'-I{out / "include"}', f'-I{prefix / "include"}']
    flags += [f'-I{d}' for d in sorted((prefix / 'include').iterdir()) if d.is_dir()]
    flags += [f'-I{sysconfig.get_paths()["include"]}', f'-I{numpy.get_include()}']
    link = [f'-L{out}', f'-L{prefix / "lib"}', f'-Wl,-rpath,{prefix / "lib"}']
    base = ['-lrosidl_runtime_c', '-lrcutils']
    gen_c = f'-l{PKG}__rosidl_generator_c'
    c_dir = gen / 'c' / 'msg' / 'detail'
    steps = [
        ('gcc', [str(c_dir / f) for f in ('tf_message__functions.c', 'tf_message__description.c',
                                          'tf_message__type_support.c')],
         f'lib{PKG}__rosidl_generator_c.so',
         ['-lgeometry_msgs__rosidl_generator_c', '-lstd_msgs__rosidl_generator_c',
          '-lbuiltin_interfaces__rosidl_generator_c']),
        ('gcc', [str(gen / 'ts_introspection_c/msg/detail/tf_message__type_support.c')],
         f'lib{PKG}__rosidl_typesupport_introspection_c.so',
         [gen_c, '-lgeometry_msgs__rosidl_typesupport_introspection_c',
          '-lrosidl_typesupport_introspection_c']),
        ('g++', [str(gen / 'ts_fastrtps_c/msg/detail/tf_message__type_support_c.cpp')],
         f'lib{PKG}__rosidl_typesupport_fastrtps_c.so',
         [gen_c, '-lgeometry_msgs__rosidl_typesupport_fastrtps_c',
          '-lrosidl_typesupport_fastrtps_c', '-lrosidl_typesupport_fastrtps_cpp', '-lfastcdr',
          '-lrmw', '-lrosidl_dynamic_typesupport']),
        ('g++', [str(gen / 'ts_c/msg/tf_message__type_support.cpp')],
         f'lib{PKG}__rosidl_typesupport_c.so', [gen_c, '-lrosidl_typesupport_c']),
        ('gcc', [str(gen / 'py/msg/_tf_message_s.c')], f'lib{PKG}__rosidl_generator_py.so',
         [gen_c, f'-l{PKG}__rosidl_typesupport_c', '-lgeometry_msgs__rosidl_generator_py',
          '-lgeometry_msgs__rosidl_generator_c']),
    ]
    for ts in TYPESUPPORTS:
        steps.append(('gcc', [str(gen / f'py/_{PKG}_s.ep.rosidl_typesupport_{ts}.c')],
                      f'{PKG}_s__rosidl_typesupport_{ts}.so',
                      [f'-l{PKG}__rosidl_generator_py', f'-l{PKG}__rosidl_typesupport_{ts}',
                       gen_c]))
    for compiler, sources, target, libs in steps:
        std = ['-std=c++17'] if compiler == 'g++' else []
        run([compiler, *flags, *std, *sources, '-o', str(out / target), *link, *libs, *base],
            out)


def install(src: Path, gen: Path, out: Path) -> None:
    """
    Libraries first, the Python package last.

    An interrupted run leaves tf2_msgs unimportable, so the next run builds again.
    """
    prefix = Path(sys.prefix)
    site = Path(sysconfig.get_paths()['purelib'])
    for lib in out.glob(f'lib{PKG}__*.so'):
        shutil.copy2(lib, prefix / 'lib' / lib.name)
    share = prefix / 'share' / PKG
    (share / 'msg').mkdir(parents=True, exist_ok=True)
    shutil.copy2(src / 'msg' / 'TFMessage.msg', share / 'msg' / 'TFMessage.msg')
    shutil.copy2(gen / 'c' / 'tmp' / 'msg' / 'TFMessage.idl', share / 'msg' / 'TFMessage.idl')
    index = prefix / 'share' / 'ament_index' / 'resource_index'
    for kind, text in (('packages', ''),
                       ('rosidl_interfaces', 'msg/TFMessage.idl\nmsg/TFMessage.msg\n')):
        (index / kind).mkdir(parents=True, exist_ok=True)
        (index / kind / PKG).write_text(text)
    stage = site / f'.{PKG}.tmp'
    shutil.rmtree(stage, ignore_errors=True)  # our own leftover from an interrupted run
    shutil.copytree(gen / 'py' / 'msg', stage / 'msg',
                    ignore=shutil.ignore_patterns('tmp', '*.c'))
    (stage / '__init__.py').write_text('')
    for ts in TYPESUPPORTS:
        shutil.copy2(out / f'{PKG}_s__rosidl_typesupport_{ts}.so', stage)
    stage.rename(site / PKG)


def main() -> None:
    if importlib.util.find_spec(PKG) is not None:
        print(f'== {PKG}: already installed')
        return
    print(f'== {PKG}: generating TFMessage with the rosidl generators and compiling it')
    with tempfile.TemporaryDirectory(prefix='tf2_msgs_build.') as tmp:
        tmp = Path(tmp)
        src, gen, out = tmp / 'src', tmp / 'gen', tmp / 'out'
        (src / 'msg').mkdir(parents=True)
        (src / 'msg' / 'TFMessage.msg').write_text(TF_MESSAGE_MSG)
        out.mkdir()
        generate(src, gen)
        build(gen, out)
        install(src, gen, out)
    print(f'== {PKG}: installed into {sys.prefix}')


if __name__ == '__main__':
    main()
