"""The errors bsms raises, each with the one-line message the bsms CLI prints for the same failure."""


class InputError(ValueError):
    """Bad input: a missing or malformed file, an unknown key, an impossible value, NaN data
    (the CLI's exit code 2)."""


class NumericalError(ArithmeticError):
    """A computation that failed: a solver step with NaN or inverted elements (exit code 3)."""


class IoError(OSError):
    """An input/output failure that is not the input's fault, such as a full disk (exit code 4)."""
