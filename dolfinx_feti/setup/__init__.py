"""The set-up: decomposition, rows and every rank's share, assembled into the FETI chain."""
