"""`fleet mavlink`: the fleet's live UAVs as MAVLink 2 vehicles (docs/mavlink.md)."""
