"""Sub-commands of ``attekf``: one module each (NAME, HELP, add_arguments, run)."""


def run_guarded(fail, body):
    """Runs body() and turns the errors every command reports alike into exit codes: bad
    input 1, bad settings 2, a failure of the native library 1 (on one line). fail(msg,
    code) prints the command's error line and returns code."""
    from ..io import InputError
    from ..native import NativeError, SettingsError

    try:
        return body()
    except InputError as exc:
        return fail(str(exc))
    except SettingsError as exc:
        return fail(str(exc), 2)
    except NativeError as exc:
        return fail(str(exc).replace("\n", " "))
