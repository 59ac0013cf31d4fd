"""Package code names the papers by their authors (Min et al.; Kim, Pearce & Amato), never "seed A/B":
"seed" is the random generator's word in this package."""

from __future__ import annotations

import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "parcover_env"
PATTERN = re.compile(r"\bseed[ -][AB]\b", re.IGNORECASE)


def test_no_seed_a_or_b_in_package_code():
    hits = [f"{p.relative_to(PACKAGE)}:{i}" for p in sorted(PACKAGE.rglob("*.py"))
            for i, line in enumerate(p.read_text().splitlines(), 1) if PATTERN.search(line)]
    assert hits == []


def test_the_pattern_finds_the_old_wording_and_spares_rng_seeds():
    assert PATTERN.search("Leader control (seed A eq. 2)") and PATTERN.search("Seed B's navigator")
    assert not PATTERN.search("reset(seed=0)") and not PATTERN.search("seed Alpha") and not PATTERN.search("seeds A")
