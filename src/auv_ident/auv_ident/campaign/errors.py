"""Exception family of the campaign tools (a branch of :class:`auv_ident.errors.IdentError`)."""
from __future__ import annotations

from auv_ident.errors import IdentError


class CampaignError(IdentError, ValueError):
    """A campaign cannot run: no logs found, a bad option, no scheduler answering."""
