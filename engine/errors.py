"""User-facing errors: the message is shown as is (Blender report, CLI stderr)."""


class EmberError(Exception):
    """Bad input or an unsupported scene; the message tells the user what to change."""


class Cancelled(Exception):
    """The user cancelled (Esc / test_break) or a stop was requested."""
