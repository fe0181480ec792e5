"""The tool's own error type: every refusal a user can see goes through it."""

from __future__ import annotations


class CalibError(Exception):
    """Bad input or a result that must not be trusted.

    The message names what is wrong, where (file, line, key, sample) and how
    to fix it. The CLI prints it without a traceback and exits non-zero.
    """

    def __init__(self, what: str, where: str | None = None, fix: str | None = None):
        self.what = what
        self.where = where
        self.fix = fix
        super().__init__(self.message)

    @property
    def message(self) -> str:
        text = f"{self.where}: {self.what}" if self.where else self.what
        if self.fix:
            text += f" ({self.fix})"
        return text
