"""The onboard planning module: one process per UAV."""
