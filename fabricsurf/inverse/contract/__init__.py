"""The measurement data contract (docs/contracts.md): read, check and write experiments."""
