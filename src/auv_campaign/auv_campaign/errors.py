"""Exception family of the auv_campaign package (campaigns over many logs, Monte Carlo)."""
from __future__ import annotations

__all__ = ['CampaignError']


class CampaignError(ValueError):
    """A campaign cannot run: no logs found, a bad option, no scheduler answering."""
