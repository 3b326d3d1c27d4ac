"""Reading and writing files: recordings in, run folders out."""
