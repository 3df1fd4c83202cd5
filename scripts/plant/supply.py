#!/usr/bin/env python3
"""A two-output power supply for the station's plant tests, served by scpipy
(an SCPI server someone else wrote) on 127.0.0.1:PORT.

Commands: *IDN?, *CLS and SYSTem:ERRor? (scpipy's own), INSTrument:NSELect,
VOLTage, CURRent, OUTPut, MEASure:VOLTage?, MEASure:CURRent?. With
--stale-error, its error queue starts with what another program left there
(-222, "Data out of range"). The first line of stdout is "listening PORT";
stdin is read and ignored (the tests' fault channel).
"""

import socket
import sys
import threading
import time

from scpipy.server import Context, Router, Server
from scpipy.shared.errors import ScpiError

router = Router()


def _value(arg):
    """An argument's text, whatever scpipy hands over."""
    text = getattr(arg, "value", arg)
    return str(text).strip()


def _outputs(context):
    return context.state.setdefault(
        "outputs", {1: {"volts": 0.0, "amps": 0.0, "on": False}, 2: {"volts": 0.0, "amps": 0.0, "on": False}}
    )


def _selected(context):
    return _outputs(context)[context.state.get("channel", 1)]


@router.register("*IDN?")
def identify(context: Context) -> str:
    return "scpipy,plant-test supply,0,1.4.1"


@router.register("INSTrument:NSELect")
def select(context: Context, channel=None):
    context.state["channel"] = int(float(_value(channel)))


@router.register("VOLTage")
def volts(context: Context, value=None):
    _selected(context)["volts"] = float(_value(value))


@router.register("CURRent")
def amps(context: Context, value=None):
    _selected(context)["amps"] = float(_value(value))


@router.register("OUTPut")
def output(context: Context, state=None):
    _selected(context)["on"] = _value(state).upper() in ("ON", "1")


@router.register("MEASure:VOLTage?")
def measure_volts(context: Context) -> str:
    out = _selected(context)
    return f"{out['volts'] if out['on'] else 0.0:.3f}"


@router.register("MEASure:CURRent?")
def measure_amps(context: Context) -> str:
    out = _selected(context)
    return f"{0.08 if out['on'] else 0.0:.3f}"


def main():
    port = int(sys.argv[1])
    stale = "--stale-error" in sys.argv[2:]

    server = Server("127.0.0.1", port, shared_context=True)
    server.include_router(router)
    if stale:
        server._context.push_error(ScpiError(-222, "Data out of range"))
    threading.Thread(target=lambda: sys.stdin.read(), daemon=True).start()

    def say_when_listening():
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                print(f"listening {port}", flush=True)
                return
            except OSError:
                time.sleep(0.05)

    threading.Thread(target=say_when_listening, daemon=True).start()
    server.run()


if __name__ == "__main__":
    main()
