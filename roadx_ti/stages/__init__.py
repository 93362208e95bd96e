"""Pipeline stages: one module per method step (options with defaults, units, validation; run)."""
