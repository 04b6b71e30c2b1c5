"""Tools over finished datasets and recipe files (verify, lint): above the stages, below the CLI."""
