"""Modbus TCP server of the soft Twido: %MW as registers, %M as coils (see `regmap`)."""

from softplc.modbus.image import ModbusImage
from softplc.modbus.protocol import process_pdu
from softplc.modbus.regmap import FUNCTIONS, ExceptionCode, ReadOnly, read_only_of
from softplc.modbus.server import ModbusTcpServer, ServerThread

__all__ = ["FUNCTIONS", "ExceptionCode", "ModbusImage", "ModbusTcpServer", "ReadOnly",
           "ServerThread", "read_only_of", "process_pdu"]
