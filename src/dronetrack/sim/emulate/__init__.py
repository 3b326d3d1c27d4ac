"""Emulated devices behind their real wire protocols, for the live drivers to talk to."""
