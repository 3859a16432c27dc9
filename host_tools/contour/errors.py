"""Errors that a user or a wire can cause: printed as one clear line."""


class UserError(Exception):
    """Bad input from the user (a file, an option, a value): exit code 2."""
