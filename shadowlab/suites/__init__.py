"""Shipped study suites (TOML, DESIGN §12): ``shadowlab suites`` lists them."""
