"""Files the fuzz tests pass where the user names a file: valid and broken checkpoints of every
kind, broken scenario files. Written once per process into a temporary directory."""

from __future__ import annotations

import functools
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np


def fuzz_settings(examples: int):
    """Hypothesis settings of the fuzz tests: ``examples`` cases, derandomized (the same cases every
    run: reproducible in CI), not shrunk (shrinking env episodes takes minutes).
    ``PARCOVER_FUZZ_EXAMPLES=N`` runs N random cases instead (a long hunt)."""
    from hypothesis import HealthCheck, Phase, settings

    hunt = os.environ.get("PARCOVER_FUZZ_EXAMPLES")
    return settings(max_examples=int(hunt) if hunt else examples, deadline=None, derandomize=not hunt,
                    database=None, suppress_health_check=list(HealthCheck),
                    phases=(Phase.explicit, Phase.generate))  # no shrinking: a failing case is shown as found


REPO = Path(__file__).resolve().parents[2]
SHIPPED = REPO / "baselines" / "checkpoints"
TORCHRL_OFFICE = SHIPPED / "ippo_office_scratch" / "policy.pt"
"""A shipped ``parcover train`` policy (office, observation version 1)."""
PPO_OFFICE = SHIPPED / "ppo_office.zip"


def bc_checkpoint(n_in: int, hidden: tuple[int, ...] = (8,), n_out: int = 2, **fields) -> dict:
    """A BC actor checkpoint dict as ``docs/lab/scripts/train_bc.py`` saves it (small net, seeded)."""
    import torch

    from parcover_env.policies.learned import make_mlp

    torch.manual_seed(0)
    net = make_mlp(n_in, n_out, hidden)
    return {"state_dict": net.state_dict(), "n_in": n_in, "n_out": n_out, "hidden": hidden,
            "obs_mean": np.zeros(n_in, np.float32), "obs_std": np.ones(n_in, np.float32), **fields}


OFFICE_OBS = 39
"""Office's observation size (v1, realistic); asserted where it matters."""


@functools.cache
def files() -> dict[str, Path]:
    """Name -> path: ``bc`` (a valid BC actor for office), ``torchrl`` (the shipped one), ``ppo``, and
    broken ones: ``empty``, ``junk`` (random bytes), ``text``, ``pickle`` (a plain pickle, not torch's
    format), ``list`` (a torch file holding a list), ``nokeys`` (a dict without the fields),
    ``bc_trunc`` (the BC file cut in half), ``bc_tail`` (cut 100 bytes short: torch says ``[Errno 22]``),
    ``bc_shape`` (weights that do not fit the declared sizes), ``bc_hidden`` (``hidden`` a string),
    ``yaml_bad`` (a scenario file that is not YAML), ``yaml_list`` (YAML, not a mapping), ``dir``
    (a directory holding broken ``bc.pt``, ``actor.pt``, ``policy.pt``, ``model.zip``)."""
    import pickle

    import torch

    d = Path(tempfile.mkdtemp(prefix="parcover_fuzz_files_"))
    out = {}

    def put(name: str, data: bytes, suffix: str = ".pt") -> None:
        out[name] = d / f"{name}{suffix}"
        out[name].write_bytes(data)

    torch.save(bc_checkpoint(OFFICE_OBS), d / "bc.pt")
    out["bc"] = d / "bc.pt"
    raw = out["bc"].read_bytes()
    put("bc_trunc", raw[: len(raw) // 2])
    put("bc_tail", raw[:-100])
    put("empty", b"")
    put("junk", np.random.default_rng(0).bytes(300))
    put("text", b"hello, not a checkpoint\n")
    put("pickle", pickle.dumps({"n_in": 3}))
    torch.save([1, 2, 3], d / "list.pt")
    out["list"] = d / "list.pt"
    torch.save({"foo": 1}, d / "nokeys.pt")
    out["nokeys"] = d / "nokeys.pt"
    torch.save({**bc_checkpoint(OFFICE_OBS), "n_in": OFFICE_OBS + 3}, d / "bc_shape.pt")
    out["bc_shape"] = d / "bc_shape.pt"
    torch.save({**bc_checkpoint(OFFICE_OBS), "hidden": "abc"}, d / "bc_hidden.pt")
    out["bc_hidden"] = d / "bc_hidden.pt"
    out["torchrl"] = d / "torchrl.pt"
    shutil.copy(TORCHRL_OFFICE, out["torchrl"])
    out["ppo"] = d / "ppo.zip"
    shutil.copy(PPO_OFFICE, out["ppo"])
    put("yaml_bad", b"map: [unclosed\n  - {", ".yaml")
    put("yaml_list", b"- 1\n- 2\n", ".yaml")
    sub = d / "dir"
    sub.mkdir()
    for name, data in (("bc.pt", b""), ("actor.pt", b"\x00" * 50), ("policy.pt", b"junk"), ("model.zip", b"junk")):
        (sub / name).write_bytes(data)
    out["dir"] = sub
    out["missing"] = d / "does_not_exist.pt"
    return out


BROKEN = ("empty", "junk", "text", "pickle", "list", "nokeys", "bc_trunc", "bc_tail", "bc_shape", "bc_hidden",
          "dir", "yaml_bad")
"""The broken checkpoint files (for a checkpoint spec every one must be one CheckpointError)."""
