"""The ground mission manager."""
