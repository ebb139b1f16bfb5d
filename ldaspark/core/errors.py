"""Exception hierarchy. Every error the library raises on purpose derives from LdasparkError,
so the CLI can print one line and exit 2 without a traceback."""


class _OneLine:
    """The message of an LdasparkError or LdasparkWarning is one line whatever text it quotes (a
    user's path or name may hold a line break or a terminal control): such characters are written
    as escapes, as repr() does (``one_line``)."""

    def __init__(self, *args):
        if args and isinstance(args[0], str):
            args = (one_line(args[0]),) + args[1:]
        super().__init__(*args)


class LdasparkError(_OneLine, Exception):
    """Base class of all ldaspark errors.

    Every error the library raises on purpose derives from it (``InputError``,
    ``TableauError``, ``NewtonError``, ``SingularSaddleError``, ...); its message is one line.
    The CLI prints that line and exits with status 2.

    Parameters
    ----------
    *args
        As for ``Exception``; a text message is kept on one line (its line breaks and control
        characters written as escapes, ``one_line``), whatever user text it quotes.

    Examples
    --------
    >>> import ldaspark
    >>> try:
    ...     ldaspark.get_method("gauss-x")
    ... except ldaspark.LdasparkError as exc:
    ...     print(type(exc).__name__)
    TableauError
    """


#: the characters ``str.splitlines`` breaks at and the other C0/C1 controls (a tab stays a tab)
_CONTROLS = {c: repr(chr(c))[1:-1] for c in [*range(0x20), 0x7f, *range(0x80, 0xa0), 0x2028, 0x2029]
             if c != 0x09}


def one_line(text: str) -> str:
    """``text`` with its line breaks and control characters written as escapes (``\\n``, ``\\x1b``,
    ``\\u2028``): one line, and nothing in it a terminal acts on."""
    return text.translate(_CONTROLS)


class TableauError(LdasparkError):
    """Malformed or unusable tableau (shapes, non-numeric entries, NaN, singular omega)."""


class SystemDefinitionError(LdasparkError):
    """Ill-posed system definition (dimensions, symbols)."""


class InconsistentInitialDataError(LdasparkError):
    """Initial data violate k(t0, q0, v0) = 0 beyond tolerance."""


class SingularSaddleError(LdasparkError):
    """The saddle matrix (4) [[L_vv, K^T], [K, 0]] is singular (or numerically so)."""


class NewtonError(LdasparkError):
    """Newton iteration for the stage equations did not converge."""

    def __init__(self, message, step=None, time=None, residual=None, iterations=None):
        super().__init__(message)
        self.step = step
        self.time = time
        self.residual = residual
        self.iterations = iterations


class InputError(LdasparkError):
    """Bad user input: NaN/inf, zero step, unknown scene or method, bad file."""


class NonFiniteError(LdasparkError):
    """A step produced NaN, infinity or complex values (L or k evaluated outside its domain),
    or an opt-in monitor (energy jump) stopped the run; names the step and its time."""

    def __init__(self, message, step=None, time=None):
        super().__init__(message)
        self.step = step
        self.time = time


class NonFiniteStepError(NonFiniteError, NewtonError):
    """Newton's iteration of a step met NaN, infinity or a complex value (L or k evaluated
    outside its domain, an overflow): a NonFiniteError (``Result.status`` -3, as the compiled
    kernels report the same step) that is also a NewtonError, so that the callers which retry a
    failed Newton step from another start (the rescue chain, the guard) still do; names the
    step, its time, the residual and the iterations."""

    def __init__(self, message, step=None, time=None, residual=None, iterations=None):
        NewtonError.__init__(self, message, step=step, time=time, residual=residual, iterations=iterations)


class LdasparkWarning(_OneLine, UserWarning):
    """Something was accepted with a note (``warnings.simplefilter("error", LdasparkWarning)``
    turns these notes into errors): a parameter value for a symbol the model does not have, an
    initial velocity changed by ``project=True``. Its text is one line, as an error's (``one_line``)."""
