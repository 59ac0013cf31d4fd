"""The simulator core: the phases of one step of ``K`` worlds (act, score, observe, outputs), the rows
of shared ``(K, ...)`` blocks they work on, and the pipeline (:func:`parcover_env.sim.pipeline.step`)
that the envs step through."""
