"""The simulator core: the phases of one step of ``K`` worlds (act, score, observe, outputs), the
pipeline (:func:`parcover_env.sim.pipeline.step`) that the envs step through, and its typed contract
with a world (:class:`parcover_env.sim.contract.StepWorld`). It imports no env: an env hands itself in
as a world, with its observation layout and feature set."""
