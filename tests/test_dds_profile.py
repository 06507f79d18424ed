"""The toolkit's Fast DDS profile (auv_contract.dds, config/dds/fastdds.xml).

Oracles: Fast DDS's own XML parser, which prints ``XMLPARSER Error`` for a profile it cannot
read (and then runs on its defaults, silently otherwise); a profile broken on purpose shows
that the check sees such an error. How much the profile shortens a join is a benchmark figure
(bench/bench_graph.py, section ``join``), not a test.
"""
from __future__ import annotations

import pathlib
import re
import subprocess
import sys

import pytest

from auv_contract.dds import PROFILE_VARIABLES, dds_profile, use_dds_profile

NODE = ('import rclpy; rclpy.init(); n = rclpy.create_node("profile_check"); '
        'n.destroy_node(); rclpy.shutdown(); print("node made")')


def _node_output(env: dict[str, str], profile: str) -> str:
    """What a process that makes one node with the profile file ``profile`` prints (without
    Fast DDS's colour codes)."""
    done = subprocess.run([sys.executable, '-c', NODE],
                          env={**env, 'FASTDDS_DEFAULT_PROFILES_FILE': profile},
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return re.sub(r'\x1b\[[0-9;]*m', '', done.stdout + done.stderr)


def test_fast_dds_reads_the_toolkits_profile_without_error(ros_env: dict[str, str],
                                                           tmp_path: pathlib.Path) -> None:
    profile = dds_profile()
    assert profile is not None and pathlib.Path(profile).is_file()
    out = _node_output(ros_env, profile)
    assert 'node made' in out and 'XMLPARSER' not in out, out
    # the same check sees a profile Fast DDS cannot read
    broken = pathlib.Path(profile).read_text().replace(
        '<sec>0</sec>', '<sec>zero</sec>', 1)
    assert broken != pathlib.Path(profile).read_text()
    (tmp_path / 'broken.xml').write_text(broken)
    assert 'XMLPARSER Error' in _node_output(ros_env, str(tmp_path / 'broken.xml'))


def test_the_profile_is_named_unless_the_user_named_one() -> None:
    env: dict[str, str] = {}
    assert use_dds_profile(env) == dds_profile()
    assert env == {'FASTDDS_DEFAULT_PROFILES_FILE': dds_profile()}
    for name in PROFILE_VARIABLES:
        mine = {name: '/home/me/my_profile.xml'}
        assert use_dds_profile(mine) == '/home/me/my_profile.xml'
        assert mine == {name: '/home/me/my_profile.xml'}
    # an empty variable names no file
    empty = {'FASTDDS_DEFAULT_PROFILES_FILE': ''}
    assert use_dds_profile(empty) == dds_profile()


def test_without_the_configuration_nothing_is_named(monkeypatch: pytest.MonkeyPatch,
                                                    tmp_path: pathlib.Path) -> None:
    monkeypatch.setenv('AUV_CONFIG_DIR', str(tmp_path / 'missing'))
    env: dict[str, str] = {}
    assert use_dds_profile(env) is None
    assert env == {}


@pytest.mark.parametrize('user', [None, *PROFILE_VARIABLES])
def test_the_workspace_environment_names_the_profile_unless_the_user_did(
        user: str | None) -> None:
    """``.venv/bin/auv-env`` (written by tools/bootstrap.sh) names the shipped profile for the
    processes started from it, and leaves a profile the user named."""
    env_file = pathlib.Path(__file__).resolve().parents[1] / '.venv' / 'bin' / 'auv-env'
    env = {'PATH': '/usr/bin:/bin', 'HOME': '/tmp'}
    if user is not None:
        env[user] = '/home/me/my_profile.xml'
    out = subprocess.run(['bash', '-c', f'. "{env_file}" && printf "%s|%s" '
                          '"${FASTDDS_DEFAULT_PROFILES_FILE:-}" '
                          '"${FASTRTPS_DEFAULT_PROFILES_FILE:-}"'],
                         env=env, capture_output=True, text=True, timeout=30, check=True)
    fastdds, fastrtps = out.stdout.split('|')
    if user is None:
        assert fastrtps == ''
        assert pathlib.Path(fastdds).read_text() == \
            pathlib.Path(dds_profile() or '').read_text()
    else:
        assert {'FASTDDS_DEFAULT_PROFILES_FILE': fastdds,
                'FASTRTPS_DEFAULT_PROFILES_FILE': fastrtps}[user] == '/home/me/my_profile.xml'
        other = fastrtps if user == 'FASTDDS_DEFAULT_PROFILES_FILE' else fastdds
        assert other == ''
