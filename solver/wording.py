"""Words for the counts that messages give, so that they agree: "1 vertex is", "2 vertices are"."""

from __future__ import annotations

__all__ = ["by_count"]


def by_count(count, one, many):
    """The phrase that agrees with ``count``: ``one`` for a count of 1, else ``many``.

    Parameters
    ----------
    count : int
    one, many : str
        The phrase for one thing and for any other number of them ("vertex is", "vertices are").

    Returns
    -------
    str
    """
    return one if count == 1 else many
