"""Test doubles: cheap stand-ins with known answers (not registered plugins)."""
