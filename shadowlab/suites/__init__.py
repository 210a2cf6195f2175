"""Shipped study suites (TOML, docs/contracts.md#study-directory): ``shadowlab suites`` lists them."""
