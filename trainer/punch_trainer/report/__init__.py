"""The report layer: what a run did, for people: motion analysis, plots, the motion-capture comparison and
Markdown run reports. Imports `learn` and `sim`."""
