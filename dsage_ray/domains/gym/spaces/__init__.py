"""The shipped gym spaces (``*.toml``, ``--space NAME``) and the setup hooks some of them name (user code, shipped
as examples: docs/GYM.md)."""
