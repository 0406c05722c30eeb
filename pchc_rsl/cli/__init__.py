"""Command-line entry points, the console scripts of pyproject.toml: each parses its arguments and calls the
library, which never imports them."""
