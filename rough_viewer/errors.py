"""The one exception type for problems the user can fix (bad file, bad option)."""


class InputError(Exception):
    """A problem with the user's input, reported as one line and exit status 2.

    The message must name the problem and, where there is one, the file.
    """
