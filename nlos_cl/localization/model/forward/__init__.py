"""The forward model on the host and the device: likelihoods (Problems), batched plates,
closed shapes' histograms, deposits, derivatives, shadows, and the observations (data).
Imports shapes only."""
