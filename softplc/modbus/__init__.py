"""Modbus TCP server of the soft Twido: %MW as registers, %M as coils (see `regmap`)."""

from .image import ModbusImage
from .protocol import process_pdu
from .regmap import FUNCTIONS, ExceptionCode, ReadOnly, read_only_of
from .server import ModbusTcpServer, ServerThread

__all__ = ["FUNCTIONS", "ExceptionCode", "ModbusImage", "ModbusTcpServer", "ReadOnly",
           "ServerThread", "read_only_of", "process_pdu"]
