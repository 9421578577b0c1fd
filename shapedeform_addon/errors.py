# SPDX-License-Identifier: GPL-3.0-or-later
"""The add-on's error, the small grammar of its messages, and how an operator's poll says why
it does not apply. Imports nothing."""


class RigError(Exception):
    """An object cannot be rigged (or its rig cannot run); the message is for the user."""


class NoPointsLeft(RigError):
    """Every point of the shape already belongs to a handle: no other handle fits."""


def with_article(noun):
    """``noun`` after "a" or "an", for messages ("an empty", "a camera").

    By its first letter: the nouns these messages use (Blender's object types and the rig kinds)
    have no silent or long-vowel exceptions such as "hour" or "unit".
    """
    return f"{'an' if noun[:1].lower() in 'aeiou' else 'a'} {noun}"


def poll_reason(operator, reason):
    """An operator's poll: True when ``reason`` is empty, else False with ``reason`` as what the
    interface shows on the greyed-out button and a script's call raises."""
    if reason:
        operator.poll_message_set(reason)
    return not reason
