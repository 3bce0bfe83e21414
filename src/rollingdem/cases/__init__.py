"""Built-in cases (the seed report's test cases)."""
