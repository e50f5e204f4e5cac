"""sagebench: artist scenes to an executable VLN benchmark."""
__version__ = "0.1.0"

from sagebench.threads import passive_by_default  # noqa: E402  before any compute pool can start

passive_by_default()
