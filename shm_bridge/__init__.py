"""Shared-memory transport between the world and a driver, and the message vocabulary every package shares."""
