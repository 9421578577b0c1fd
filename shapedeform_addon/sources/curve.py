# SPDX-License-Identifier: GPL-3.0-or-later
from . import RigError


def prepare(obj, settings):
    raise RigError("not yet")
