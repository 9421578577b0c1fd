# SPDX-License-Identifier: GPL-3.0-or-later
def is_image_plane(obj):
    return False
