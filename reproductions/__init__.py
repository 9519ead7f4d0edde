"""reproductions plug-ins for prtbench (registered through entry points in pyproject.toml)."""
