"""Shipped scenario YAMLs, installed as ``parcover_env.configs`` (see pyproject.toml)."""
