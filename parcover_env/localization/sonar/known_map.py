"""The known map's sonar features and relaxed sectors, computed once per map."""

from __future__ import annotations

from functools import lru_cache

from parcover_env.config import MapConfig
from parcover_env.localization.sonar.features import MapFeature, map_features
from parcover_env.localization.sonar.sectors import Sector, compute_sectors
from parcover_env.world.map_model import MapModel, map_model

__all__ = ["known_map_features"]


@lru_cache(maxsize=8)
def _cached_map(map_cfg: MapConfig, range_max: float, rule: int):
    known = map_model(map_cfg, include_unknown=False)
    feats = map_features(known)
    sectors = compute_sectors(known, range_max, rule=rule, features=feats)
    return known, feats, sectors


def known_map_features(map_cfg: MapConfig, range_max: float, rule: int = 2
                       ) -> tuple[MapModel, list[MapFeature], list[Sector]]:
    """Known map (no unknown obstacles), its features and relaxed sectors; cached per map config."""
    try:
        return _cached_map(map_cfg, float(range_max), int(rule))
    except TypeError:  # unhashable config: compute without the cache
        return _cached_map.__wrapped__(map_cfg, float(range_max), int(rule))
