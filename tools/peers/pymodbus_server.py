"""A bare pymodbus TCP server with a plain datastore: the baseline of the Modbus benchmark.

    python tools/peers/pymodbus_server.py PORT     (0 = any free port; prints "listening PORT")
"""

from __future__ import annotations

import asyncio
import logging
import sys
import warnings


async def serve(port: int) -> None:
    from pymodbus.datastore import (
        ModbusDeviceContext,
        ModbusSequentialDataBlock,
        ModbusServerContext,
    )
    from pymodbus.server import ModbusTcpServer

    with warnings.catch_warnings():  # ModbusDeviceContext is deprecated in pymodbus 3.16
        warnings.simplefilter("ignore")
        device = ModbusDeviceContext(hr=ModbusSequentialDataBlock(1, [0] * 1000))
        context = ModbusServerContext(devices={1: device})
    server = ModbusTcpServer(context, address=("127.0.0.1", port))
    await server.listen()
    sock = server.transport.sockets[0] if hasattr(server.transport, "sockets") else None
    bound = sock.getsockname()[1] if sock else port
    print(f"listening {bound}", flush=True)
    await server.serving


def main() -> None:
    logging.disable(logging.WARNING)
    asyncio.run(serve(int(sys.argv[1]) if len(sys.argv) > 1 else 0))


if __name__ == "__main__":
    main()
