"""File formats: atomic writes, the result CSV and G-code writers."""
