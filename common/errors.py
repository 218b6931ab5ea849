"""The one error type users see.

Error policy: anything a user can cause (a malformed file, a wrong model, a missing camera, a bad
setting) raises :class:`MomlocError` with a message that names the thing and what is wrong. The CLI
prints that message as one line and exits non-zero; it never shows a traceback for these. Any other
exception is a bug and keeps its traceback.
"""


class MomlocError(Exception):
    """A problem the user can fix, described in one line."""


def shorten(text: object, limit: int = 160) -> str:
    """``text`` cut to ``limit`` characters with an ellipsis in the middle.

    Why: error messages and logs echo user input (paths, names); a 10 MB path in a request must
    not become a 10 MB log line or response. The start and the end stay, which is what tells two
    paths apart.
    """
    value = str(text)
    if len(value) <= limit:
        return value
    keep = max(limit - 1, 2) // 2
    return f"{value[:keep]}…{value[-keep:]}"
