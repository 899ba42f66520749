"""What an adapter says when the host library it wraps is not installed."""

from __future__ import annotations


def missing_extra(adapter: str, extra: str, error: ModuleNotFoundError) -> ModuleNotFoundError:
    """The error to raise from ``adapter`` when importing ``error.name`` failed.

    Args:
        adapter: The module that needs the library (``cpmx.torchrl``).
        extra: The package extra that installs it (``torchrl``).
        error: The failed import.

    Returns:
        A ``ModuleNotFoundError`` naming the missing module and how to install it.

    """
    package = (error.name or "?").partition(".")[0]
    return ModuleNotFoundError(
        f"{adapter} needs the module `{package}`, which is not installed: "
        f"pip install './python[{extra}]' (from the cpmx checkout) installs what {adapter} needs",
        name=package,
    )
