"""Reports: plots, the 3D render and HTML pages for smoothing results and diagnosis findings."""
