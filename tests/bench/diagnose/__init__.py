"""Harnesses of the diagnosis benchmark: blind cases, their answer key (oracle, SNR)."""
