"""The report's HTML: the page, its tiles, figures, blocks and a run's index."""
