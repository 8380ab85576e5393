"""The harness's error for bad input: a file, an option or data the user can fix.

`python -m harness` prints a `UserError` as one line and exits with status 2; any other
exception is a defect and keeps its traceback. It subclasses ValueError, so callers that
catch ValueError from a parser keep working.
"""

from __future__ import annotations


class UserError(ValueError):
    """Bad input the user can fix; the message names the field and its allowed values."""
