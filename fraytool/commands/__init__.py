"""The fraytool command line: every command lives here (main.py parses and dispatches)."""
