"""Learning: demonstrations, preprocessing, segmentation, labelling, imitation, policy search, templates."""
