"""The toolkit's Fast DDS profile, given to its processes unless the user gives one.

``config/dds/fastdds.xml`` changes two timings of Fast DDS (its comment gives them and why):
participants announce themselves every 0.5 s instead of 3 s, so that a process joining a
running graph finds every node within about 0.5 s, and reliable writers send a heartbeat every
100 ms instead of 3 s, so that a lost sample is sent again within about 0.1 s. Fast DDS reads the
profile file named by ``FASTDDS_DEFAULT_PROFILES_FILE`` (or the older
``FASTRTPS_DEFAULT_PROFILES_FILE``) when a process creates its first participant; a user's
file in either variable is left as it is. ``.venv/bin/auv-env`` names the same file for every
process started from it (``tools/bootstrap.sh``), under the same rule.
"""
from __future__ import annotations

import os
from collections.abc import MutableMapping

from auv_contract.files import config_path

__all__ = ['PROFILE_VARIABLES', 'dds_profile', 'use_dds_profile']

PROFILE_VARIABLES = ('FASTDDS_DEFAULT_PROFILES_FILE', 'FASTRTPS_DEFAULT_PROFILES_FILE')
"""The environment variables Fast DDS takes its profile file from."""


def dds_profile() -> str | None:
    """Path of the toolkit's profile file, None where the shipped configuration is not found
    (no workspace set up: the command says so where it needs the configuration)."""
    try:
        return str(config_path('dds', 'fastdds.xml'))
    except FileNotFoundError:
        return None


def use_dds_profile(env: MutableMapping[str, str] | None = None) -> str | None:
    """Name the toolkit's profile in ``env`` (default: this process's environment, before its
    first participant) unless a profile file is named there already.

    Returns
    -------
    str or None
        The profile file ``env`` names afterwards (the user's or the toolkit's), None if
        neither.
    """
    env = os.environ if env is None else env
    for name in PROFILE_VARIABLES:
        if env.get(name):
            return env[name]
    profile = dds_profile()
    if profile is not None:
        env['FASTDDS_DEFAULT_PROFILES_FILE'] = profile
    return profile
