"""refspatial-gen: procedural, checked, reproducible spatial-referring QA data for robot VLMs."""

__version__ = "0.1.0"
SCHEMA_VERSION = 1
