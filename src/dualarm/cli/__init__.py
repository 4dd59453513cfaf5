"""The `dualarm` command: one module per top-level command; `dualarm.cli.main` parses and dispatches."""
