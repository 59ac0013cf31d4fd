"""Policies that act from observations: the registry (``make_policy``), simple and learned ones.

The scripted expert lives in :mod:`parcover_env.expert`; the registry builds it by name.
"""

from parcover_env.policies.registry import BASIC_POLICIES, POLICY_SPECS, check_policy_spec, make_policy
from parcover_env.policies.simple import RandomPolicy, WaypointPolicy

__all__ = ["BASIC_POLICIES", "POLICY_SPECS", "check_policy_spec", "make_policy", "RandomPolicy", "WaypointPolicy"]
