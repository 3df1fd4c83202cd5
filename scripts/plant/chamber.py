#!/usr/bin/env python3
"""A temperature chamber for the station's plant tests, served by pymodbus
(a Modbus TCP server someone else wrote) on 127.0.0.1:PORT.

Holding registers (0-based, 0.1 degC per count): 100 setpoint, 101 process
value, 102 run (1) / stop (0), 103 alarm word, 104 purge. The air follows
the setpoint at 10 degC/s while running.

Faults, one command a line on stdin:
  busy N      the next N replies are exception 06 (server device busy)
  outage S    the server goes away for S seconds (connections refused)
  alarm W     the alarm word becomes W (0 clears it)
  reboot S    the controller restarts: away for S seconds, then back with
              its power-on setpoint (23.0 degC) and stopped
  silence S   from the next reply on, no reply is sent for S seconds (a
              link that drops bytes; the connection stays up); answered
              once the silence is over, with the replies it dropped
Each command is acknowledged on stdout ("ok <command>"); the first line of
stdout is "listening PORT".
"""

import asyncio
import sys

from pymodbus.datastore import (
    ModbusSequentialDataBlock,
    ModbusServerContext,
    ModbusSlaveContext,
)
from pymodbus.pdu import ExceptionResponse
from pymodbus.server import ModbusTcpServer

# pymodbus's slave context adds one to a request's address (its blocks
# are 1-based): the block index of register N is N + 1.
SETPOINT, PV, RUN, ALARMS, PURGE = 101, 102, 103, 104, 105


class Chamber:
    def __init__(self, port):
        self.port = port
        self.busy = 0
        self.block = ModbusSequentialDataBlock(0, [0] * 200)
        self.block.setValues(PV, [230])
        self.block.setValues(SETPOINT, [230])
        self.context = ModbusServerContext(
            slaves=ModbusSlaveContext(hr=self.block, ir=self.block),
            single=True,
        )
        self.server = None
        self.silence_s = 0.0
        self.silent_until = None
        self.dropped = 0
        self.silence_over = None

    def trace_packet(self, sending, data):
        if not sending or self.silence_s <= 0:
            return data
        now = asyncio.get_running_loop().time()
        if self.silent_until is None:
            self.silent_until = now + self.silence_s
        if now < self.silent_until:
            self.dropped += 1
            return b""
        self.silence_s = 0.0
        self.silent_until = None
        if self.silence_over is not None:
            self.silence_over.set()
        return data

    def trace_pdu(self, sending, pdu):
        if sending and self.busy > 0 and not pdu.isError():
            self.busy -= 1
            return ExceptionResponse(
                pdu.function_code,
                ExceptionResponse.SLAVE_BUSY,
                slave=pdu.dev_id,
                transaction=pdu.transaction_id,
            )
        return pdu

    async def serve(self):
        self.server = ModbusTcpServer(
            self.context,
            address=("127.0.0.1", self.port),
            trace_pdu=self.trace_pdu,
            trace_packet=self.trace_packet,
        )
        await self.server.serve_forever()

    async def physics(self):
        while True:
            await asyncio.sleep(0.1)
            if self.block.getValues(RUN, 1)[0] == 1:
                sp = self.block.getValues(SETPOINT, 1)[0]
                pv = self.block.getValues(PV, 1)[0]
                step = 10  # counts of 0.1 degC per 0.1 s
                if abs(sp - pv) <= step:
                    pv = sp
                else:
                    pv += step if sp > pv else -step
                self.block.setValues(PV, [pv])

    async def commands(self):
        loop = asyncio.get_running_loop()
        reader = asyncio.StreamReader()
        await loop.connect_read_pipe(
            lambda: asyncio.StreamReaderProtocol(reader), sys.stdin
        )
        while True:
            line = (await reader.readline()).decode().strip()
            if not line:
                if reader.at_eof():
                    return
                continue
            what, _, value = line.partition(" ")
            if what == "busy":
                self.busy = int(value)
            elif what == "alarm":
                self.block.setValues(ALARMS, [int(value)])
            elif what == "reboot":
                await self.server.shutdown()
                self.block.setValues(SETPOINT, [230])
                self.block.setValues(RUN, [0])
                print("ok " + line + " (down)", flush=True)
                await asyncio.sleep(float(value))
                asyncio.create_task(self.serve())
                await asyncio.sleep(0.2)
            elif what == "silence":
                self.dropped = 0
                self.silence_over = asyncio.Event()
                self.silence_s = float(value)
                await self.silence_over.wait()
                line += f" (dropped {self.dropped} replies)"
            elif what == "outage":
                await self.server.shutdown()
                print("ok " + line + " (down)", flush=True)
                await asyncio.sleep(float(value))
                asyncio.create_task(self.serve())
                await asyncio.sleep(0.2)
            print("ok " + line, flush=True)


async def main():
    port = int(sys.argv[1])
    chamber = Chamber(port)
    asyncio.create_task(chamber.serve())
    asyncio.create_task(chamber.physics())
    while True:
        try:
            _, writer = await asyncio.open_connection("127.0.0.1", port)
            writer.close()
            break
        except OSError:
            await asyncio.sleep(0.05)
    print(f"listening {port}", flush=True)
    await chamber.commands()


if __name__ == "__main__":
    asyncio.run(main())
