"""Mutated recipes (filled in below)."""
def recipe_cases():
    return []
