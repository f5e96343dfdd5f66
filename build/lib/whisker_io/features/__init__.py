"""Features of whisked contacts: the tactile image, point feature histograms
(PFH) and the slope distribution (SDA) of Ch.5."""
