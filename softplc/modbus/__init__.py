"""Modbus TCP server of the soft Twido: %MW as registers, %M as coils (see `regmap`).

The names below load their module on first use (PEP 562): a command that needs only the
register map does not load the server, the image and the persistence. The codec every side
shares is the top-level `softplc.modbus_codec` (the runtime's EXCH uses it too)."""

from importlib import import_module
from typing import Any

_WHERE = {"ModbusImage": "image", "process_pdu": "protocol", "FUNCTIONS": "regmap",
          "ExceptionCode": "regmap", "ReadOnly": "regmap", "read_only_of": "regmap",
          "ModbusTcpServer": "server", "ServerThread": "server"}

__all__ = sorted(_WHERE)


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(import_module(f"{__name__}.{_WHERE[name]}"), name)
