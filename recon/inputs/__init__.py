"""What a reconstruction starts from: the photos' pose priors and camera seed, the tags' offset, similarity fits."""
