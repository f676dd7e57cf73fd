"""The detailizers: the learned DECOLLAGE pyramid GAN and the non-learned `upsample` baseline."""
