"""Modbus TCP server of the soft Twido: %MW as registers, %M as coils (see `regmap`)."""

from .image import ModbusImage
from .protocol import process_pdu
from .regmap import FUNCTIONS, ExceptionCode, ReadOnly, parse_read_only
from .server import ModbusTcpServer, ServerThread

__all__ = ["FUNCTIONS", "ExceptionCode", "ModbusImage", "ModbusTcpServer", "ReadOnly",
           "ServerThread", "parse_read_only", "process_pdu"]
