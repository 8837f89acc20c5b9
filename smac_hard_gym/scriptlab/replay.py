"""A stand-in chat server that replays recorded replies, for running the lab offline (timing the non-LLM part of a
round, demos). It speaks the same protocol as the real servers: ``POST /v1/chat/completions``.

A plan file maps each role (``planner``, ``red_coder``, ``blue_coder``, ``critic``: the ``ROLE:`` line of the
system prompt) to a list of reply files in its folder, served in order (the last one repeats). A ``.json`` file is
a whole recorded response; any other file is the reply's text::

    python -m smac_hard_gym.scriptlab.replay tests/data/scriptlab/settle.json --port 8099 &
    smac-hard-gym scriptlab --map 2s3z --rounds 1 --endpoint http://127.0.0.1:8099/v1
"""

from __future__ import annotations

import argparse
import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

__all__ = ["ReplayServer"]


class ReplayServer:
    """Serves the replies a plan file lists, per role, on 127.0.0.1 (``port`` 0: any free port; see ``url``)."""

    def __init__(self, plan: str | Path, port: int = 0) -> None:
        plan = Path(plan)
        self.folder = plan.parent
        self.queues: dict[str, list[str]] = {k: list(v) for k, v in json.loads(plan.read_text()).items()}
        self.served = 0
        owner = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args) -> None:
                pass

            def do_POST(self) -> None:
                body = json.loads(self.rfile.read(int(self.headers.get("Content-Length", 0))) or b"{}")
                data = owner.answer(body)
                self.send_response(200)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

        self.httpd = ThreadingHTTPServer(("127.0.0.1", port), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/v1"

    def answer(self, body: dict) -> bytes:
        first = str(body.get("messages", [{}])[0].get("content", "")).split("\n", 1)[0]
        role = first.removeprefix("ROLE:").strip()
        queue = self.queues.get(role) or ["(no recorded reply for this role)"]
        name = queue.pop(0) if len(queue) > 1 else queue[0]
        self.served += 1
        path = self.folder / name
        text = path.read_text() if path.is_file() else name
        if path.suffix == ".json":
            return text.encode()
        return json.dumps({"object": "chat.completion", "model": body.get("model", ""),
                           "choices": [{"index": 0, "message": {"role": "assistant", "content": text},
                                        "finish_reason": "stop"}],
                           "usage": {"prompt_tokens": 0, "completion_tokens": 0}}).encode()

    def start(self) -> ReplayServer:
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()
        return self

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


def main() -> None:
    parser = argparse.ArgumentParser(description="serve recorded chat replies (see the module docstring)")
    parser.add_argument("plan", help="a JSON plan: role -> list of reply files next to it")
    parser.add_argument("--port", type=int, default=8099)
    args = parser.parse_args()
    server = ReplayServer(args.plan, args.port)
    print(f"replaying {args.plan} at {server.url}", flush=True)
    server.httpd.serve_forever()


if __name__ == "__main__":
    main()
