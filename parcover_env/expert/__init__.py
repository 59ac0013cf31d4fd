"""The scripted experts: decisions only (where to stop and scan, when to split, formation keeping).

:func:`expert_for` returns the expert that suits a scenario; the classes are
:class:`~parcover_env.expert.scripted.ScriptedExpert` (leaders drive the plan, followers keep
formation; Min et al.) and :class:`~parcover_env.expert.navigator.SonarNavigator` (stop-and-scan
sonar localization; Kim, Pearce & Amato 2001).
"""

from __future__ import annotations

__all__ = ["expert_for"]


def expert_for(env, **kwargs):
    """The scripted expert of ``env``'s scenario, built from the env's public spec (a ``Policy``).

    ``localization: sonar`` (with sonar observations): a
    :class:`~parcover_env.expert.navigator.SonarNavigator`; otherwise a
    :class:`~parcover_env.expert.scripted.ScriptedExpert`. ``kwargs`` go to that class's ``for_env``.
    """
    if env.scenario.localization == "sonar" and env.sonar is not None:
        from parcover_env.expert.navigator import SonarNavigator

        return SonarNavigator.for_env(env, **kwargs)
    from parcover_env.expert.scripted import ScriptedExpert

    return ScriptedExpert.for_env(env, **kwargs)
