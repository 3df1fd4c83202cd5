"""A plant's webhook receiver, as an MES would write one with Python's own
http.server and hmac (not the station's code): it checks each delivery's
X-Spinbench-Signature (HMAC-SHA256 of "TIMESTAMP.BODY" under the shared
secret) and appends one JSON line per request to LOG. Run by
crates/station/tests/web_webhooks.rs.

    python3 webhook_receiver.py SECRET_FILE LOG [--fail-first N]

Prints the port it listens on (loopback), then serves until killed. With
--fail-first N, the first N requests are answered 503 (a receiver that is
down), to see the station try again.
"""

import hashlib
import hmac
import http.server
import json
import sys
import threading

secret_file, log_path = sys.argv[1], sys.argv[2]
fail_first = int(sys.argv[4]) if len(sys.argv) > 4 and sys.argv[3] == "--fail-first" else 0
secret = open(secret_file, "rb").read().strip()
lock = threading.Lock()
seen = [0]


class Receiver(http.server.BaseHTTPRequestHandler):
    def do_POST(self):
        length = int(self.headers.get("Content-Length", "0"))
        body = self.rfile.read(length)
        timestamp = self.headers.get("X-Spinbench-Timestamp", "")
        wanted = "sha256=" + hmac.new(secret, timestamp.encode() + b"." + body, hashlib.sha256).hexdigest()
        got = self.headers.get("X-Spinbench-Signature", "")
        with lock:
            seen[0] += 1
            refuse = seen[0] <= fail_first
            try:
                parsed = json.loads(body)
            except ValueError:
                parsed = None
            with open(log_path, "a") as log:
                log.write(
                    json.dumps(
                        {
                            "event": self.headers.get("X-Spinbench-Event"),
                            "delivery": self.headers.get("X-Spinbench-Delivery"),
                            "signature_valid": hmac.compare_digest(wanted, got),
                            "content_type": self.headers.get("Content-Type"),
                            "answered": 503 if refuse else 204,
                            "body": parsed,
                        }
                    )
                    + "\n"
                )
        self.send_response(503 if refuse else 204)
        self.send_header("Content-Length", "0")
        self.end_headers()

    def log_message(self, *args):
        pass


server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Receiver)
print(server.server_address[1], flush=True)
server.serve_forever()
