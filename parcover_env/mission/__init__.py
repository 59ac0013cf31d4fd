"""The mission over ``(K, N)`` arrays: the team (Alg. 1 splits, promotions, hand-over), reward terms and
episode metrics (route progress and KPOI visits still live in :mod:`parcover_env.scenarios.progress`)."""
