"""Photo and render brought to one space and compared: images, error maps, regions, noise."""
