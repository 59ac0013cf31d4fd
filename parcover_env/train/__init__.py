"""The training stack on the batched worlds (issue 41 item 4: TorchRL under ``parcover_env/train/``).

:mod:`~parcover_env.train.world_groups` steps ``B`` worlds of a scenario or a map pool as arrays;
:mod:`~parcover_env.train.batched_env` is them as one TorchRL env of batch size ``[B]``, the env
``parcover train`` collects from (``collector_env: batched``). torch and torchrl are imported only
by the latter.
"""
