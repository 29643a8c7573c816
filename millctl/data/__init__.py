"""Data files shipped with millctl (links to the repository's ``config/``)."""
