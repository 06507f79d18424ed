"""Exception family of the auv_bag package.

Every error raised on bad input (a missing or damaged bag, a topic that is not there, a message
that does not decode, a writer given the wrong type) is a :class:`BagError`, so a command line
front end can print one line ``error: ...`` and exit 1 without catching programming errors.
"""
from __future__ import annotations


class BagError(ValueError):
    """A bag cannot be read or written: missing, damaged, wrong topic, bad timestamps."""
