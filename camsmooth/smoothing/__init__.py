"""Smoothing: local frames and lead/tilt windows (orientation), the row NLP (nlp), and the
pipeline that runs the methods over a whole program (pipeline, result)."""
