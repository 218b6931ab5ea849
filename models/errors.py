"""The one error type users see.

Error policy: anything a user can cause (a malformed file, a wrong model, a missing camera, a bad
setting) raises :class:`MomlocError` with a message that names the thing and what is wrong. The CLI
prints that message as one line and exits non-zero; it never shows a traceback for these. Any other
exception is a bug and keeps its traceback.
"""


class MomlocError(Exception):
    """A problem the user can fix, described in one line."""
