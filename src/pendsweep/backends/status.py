"""Status of a simulated point: kernel codes mapped to names and messages."""

from __future__ import annotations

from enum import Enum

from ..kernels import STATUS_DIVERGED, STATUS_OK, STATUS_UNSTABLE


class Status(str, Enum):  # noqa: UP042 - str() must stay the enum name, as in existing messages
    """Outcome of one simulated point; stored by value in result files."""

    OK = "ok"
    DIVERGED = "diverged"
    UNSTABLE = "unstable"

    @property
    def message(self) -> str:
        return _MESSAGES[self]

    @classmethod
    def from_code(cls, code: int) -> Status:
        return _FROM_CODE[int(code)]


_MESSAGES = {
    Status.OK: "integrated to the end of the record",
    Status.DIVERGED: "the state became non-finite; the point was stopped",
    Status.UNSTABLE: "the substructured loop went unstable (growing high-frequency actuator motion)",
}
_FROM_CODE = {STATUS_OK: Status.OK, STATUS_DIVERGED: Status.DIVERGED, STATUS_UNSTABLE: Status.UNSTABLE}
