"""The scenario schema: scenario, robot and instrument TOML files validated by schema, and the built-in data."""
