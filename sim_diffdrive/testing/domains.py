# Copyright 2026 motion_challenges contributors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
The ROS domains of test runs: one per pytest worker and graph, none shared with another run.

A run claims a block of DOMAIN_BLOCK domains in 1..100 with a lock file that every user's runs
share (DOMAIN_LOCKS), exports its first as SIM_GRAPH_DOMAIN_ID (and ROS_DOMAIN_ID, with
discovery kept on this machine), and its processes inherit it.
"""

import contextlib
import fcntl
import os
import random
import warnings

DOMAIN_VARIABLE = 'SIM_GRAPH_DOMAIN_ID'
# The pytest-xdist worker whose domain SIM_GRAPH_DOMAIN_ID already is (isolated_domain_id).
WORKER_VARIABLE = 'SIM_GRAPH_DOMAIN_WORKER'
# Fast DDS's highest: a higher domain's ports pass 65535, and the process exits without a word.
MAX_DOMAIN_ID = 232
# Domains a run claims at once: one for each of up to this many pytest workers.
DOMAIN_BLOCK = 4
# Where runs lock their blocks of domains: one place for the whole machine.
DOMAIN_LOCKS = '/tmp/sim_graph_domains'
_claims = []  # the lock files (descriptors) this process holds (claim_domains)
_spares = []  # the domains of blocks this process claimed for a graph beside another


def isolated_domain_id():
    """
    Return this process's ROS domain, claimed once and exported; discovery local.

    The first call claims a block (claim_domains) and stores its first domain in
    SIM_GRAPH_DOMAIN_ID (set that to pin one); child processes get it as ROS_DOMAIN_ID.  A
    pytest-xdist worker gwN given a domain (pinned, or its run's block) takes it + N.
    """
    given = os.environ.get(DOMAIN_VARIABLE)
    domain = claim_domains() if given is None else _domain_number(given)
    worker = os.environ.get('PYTEST_XDIST_WORKER')
    if worker and os.environ.get(WORKER_VARIABLE) != worker:
        os.environ[WORKER_VARIABLE] = worker  # its child processes: the domain is theirs too
        if given is not None:
            domain = _domain_number(domain + int(worker[2:]), f' + {worker[2:]} (worker {worker})')
    os.environ[DOMAIN_VARIABLE] = os.environ['ROS_DOMAIN_ID'] = str(domain)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return domain


def _domain_number(value, how=''):
    """Return value as a domain, or ValueError naming SIM_GRAPH_DOMAIN_ID and the valid range."""
    domain = int(value) if str(value).isdigit() else -1
    if not 0 <= domain <= MAX_DOMAIN_ID:
        raise ValueError(f'{DOMAIN_VARIABLE}={os.environ[DOMAIN_VARIABLE]}{how}: a ROS domain is '
                         f'a whole number from 0 to {MAX_DOMAIN_ID} (Fast DDS)')
    return domain


def claim_domains(directory=None):
    """
    Claim a free block of domains for this process's lifetime; return the block's first domain.

    A block is held by a lock on its file in directory (DOMAIN_LOCKS, or SIM_GRAPH_DOMAIN_LOCKS:
    one for every user, as domains are the machine's).  When none is free, one is shared.
    """
    # Fast DDS maps a domain to UDP ports; 1..100 stays clear of 0 (everyone's default) and of
    # the top of the valid range.
    starts = list(range(1, 101, DOMAIN_BLOCK))
    random.SystemRandom().shuffle(starts)
    directory = directory or os.environ.get('SIM_GRAPH_DOMAIN_LOCKS', DOMAIN_LOCKS)
    with contextlib.suppress(OSError):
        os.makedirs(directory, exist_ok=True)
        os.chmod(directory, 0o1777)  # every user's runs lock here (refused if not ours)
    for start in starts:
        try:
            # Read-only is enough for flock, so a file another user made serves as well.
            lock = os.open(os.path.join(directory, f'{start}.lock'), os.O_RDONLY | os.O_CREAT,
                           0o666)
        except OSError:
            continue
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(lock)
            continue
        _claims.append(lock)  # held open (and so locked) until this process ends
        return start
    warnings.warn(f'Every block of ROS domains 1-100 is held by another run on this machine: '
                  f'sharing domain {starts[0]}, whose nodes may hear each other (set '
                  f'{DOMAIN_VARIABLE} to a free domain)', RuntimeWarning, stacklevel=2)
    return starts[0]


def spare_domain(taken):
    """Return a domain not in taken, of a block this process holds (claimed once needed)."""
    if not (free := [d for d in _spares if d not in taken]):
        start = claim_domains()
        _spares.extend(free := list(range(start, start + DOMAIN_BLOCK)))
    return free[0]
