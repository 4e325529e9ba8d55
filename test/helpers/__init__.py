"""Builders and readers shared by the tests."""
