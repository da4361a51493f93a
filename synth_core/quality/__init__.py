"""Motion quality: metrics after FK, the standard and edge evaluations, the herd simulator used
for them, the paper's on-the-fly baseline."""
