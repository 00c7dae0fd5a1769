"""What the map layer raises and warns (a leaf: the loader and the resolver both use it)."""
from __future__ import annotations


class MapFileError(ValueError):
    """A map file that cannot be used: unreadable, truncated, wrong schema, inconsistent,
    or its content does not match its hash (tampered or damaged)."""


class MapIntegrityWarning(UserWarning):
    """A map that carries no content hash: nothing proves its values are the built ones."""
