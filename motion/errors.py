"""The one error type a user can cause: its message is a single sentence naming the
problem and the fix. The CLI prints it without a traceback; the daemon logs and counts it."""


class UserError(Exception):
    """Bad file, bad option, bad packet or bad checkpoint: say what and how to fix it."""
