"""Policies that act from observations: the ``Policy`` protocol, the registry by name, simple and learned ones.

The scripted expert lives in :mod:`parcover_env.expert`; the registry builds it by name (``expert``).
"""

from parcover_env.policies.protocol import Actions, Observations, Policy
from parcover_env.policies.registry import (
    BASIC_POLICIES,
    POLICIES,
    POLICY_SPECS,
    PolicyEntry,
    check_policy_spec,
    make_policy,
    policy_specs,
)
from parcover_env.policies.simple import RandomPolicy, WaypointPolicy

__all__ = ["Policy", "Observations", "Actions", "POLICIES", "PolicyEntry", "BASIC_POLICIES", "POLICY_SPECS",
           "check_policy_spec", "make_policy", "policy_specs", "RandomPolicy", "WaypointPolicy"]
