"""A minimal OpenAI chat-completions client on the standard library, and the lab's transcript.

``POST {endpoint}/chat/completions`` with ``{"model", "messages", "temperature"}``; the answer is
``choices[0].message.content`` and the token counts ``usage.prompt_tokens`` / ``usage.completion_tokens`` (0 where a
server leaves them out). Every failure (server unreachable, time-out, HTTP error, a reply that is not the protocol's
JSON) is an :class:`LLMError` with a one-line message.

The API key is read from an environment variable only (:data:`KEY_ENV`, or the one named by ``key_env``); it is
sent in the ``Authorization`` header and never written anywhere: the transcript and error messages are scrubbed of
it in case a server echoes it back. ``OPENAI_API_KEY`` is used only for OpenAI's own host, so a key meant for OpenAI
is never sent to some other server.
"""

from __future__ import annotations

import json
import os
import time
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["KEY_ENV", "OPENAI_KEY_ENV", "ChatClient", "ChatReply", "LLMError", "Transcript", "api_key"]

KEY_ENV = "SMAC_HARD_GYM_LLM_KEY"  # the lab's own variable: sent to whatever endpoint is configured
OPENAI_KEY_ENV = "OPENAI_API_KEY"  # only sent to api.openai.com
_OPENAI_HOST = "api.openai.com"
_ERROR_BODY = 300  # characters of an HTTP error's body shown in the message


class LLMError(RuntimeError):
    """The language-model server could not be used: unreachable, too slow, an HTTP error or a malformed reply."""


@dataclass
class ChatReply:
    """One completion: its text, token counts and wall time."""

    content: str
    prompt_tokens: int
    completion_tokens: int
    seconds: float


def api_key(endpoint: str, key_env: str | None = None) -> str | None:
    """The key for ``endpoint`` from the environment: ``key_env`` if named, else :data:`KEY_ENV`, else
    ``OPENAI_API_KEY`` when the endpoint is OpenAI's host; None when there is none (local servers need none)."""
    if key_env:
        return os.environ.get(key_env) or None
    key = os.environ.get(KEY_ENV)
    if key:
        return key
    if urllib.parse.urlparse(endpoint).hostname == _OPENAI_HOST:
        return os.environ.get(OPENAI_KEY_ENV) or None
    return None


def _one_line(text: str, limit: int = _ERROR_BODY) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit] + "..."


class ChatClient:
    """Chat completions from one server and model (see the module docstring).

    ``timeout`` bounds each request in seconds; ``retries`` more tries follow a time-out, a refused connection or
    an HTTP 429/5xx, ``backoff`` seconds apart (doubling). ``transcript`` (optional) records every exchange.
    """

    def __init__(self, endpoint: str, model: str, *, key_env: str | None = None, timeout: float = 120.0,
                 retries: int = 1, backoff: float = 2.0, temperature: float | None = 0.7,
                 transcript: Transcript | None = None) -> None:
        if not endpoint.startswith(("http://", "https://")):
            raise ValueError(f"--endpoint must be an http:// or https:// URL, got {endpoint!r}")
        self.endpoint = endpoint.rstrip("/")
        self.url = self.endpoint + "/chat/completions"
        self.model = model
        self.timeout = float(timeout)
        self.retries = max(0, int(retries))
        self.backoff = float(backoff)
        self.temperature = temperature
        self.transcript = transcript
        self._key = api_key(self.endpoint, key_env)  # kept private: never logged, never written
        self.prompt_tokens = 0
        self.completion_tokens = 0
        self.calls = 0

    def scrub(self, text: str) -> str:
        """``text`` with the API key (if any) replaced by ``***``."""
        return text.replace(self._key, "***") if self._key else text

    def chat(self, messages: list[dict[str, str]], *, role: str = "", round_no: int = 0) -> ChatReply:
        """One completion for ``messages``; ``role`` and ``round_no`` label the transcript entry."""
        body: dict[str, Any] = {"model": self.model, "messages": messages}
        if self.temperature is not None:
            body["temperature"] = self.temperature
        start = time.perf_counter()
        doc = self._post(json.dumps(body).encode())
        try:
            content = doc["choices"][0]["message"]["content"]
        except (KeyError, IndexError, TypeError):
            raise LLMError(f"the reply from {self.url} has no choices[0].message.content: "
                           f"{self.scrub(_one_line(json.dumps(doc)))}") from None
        if not isinstance(content, str):
            raise LLMError(f"the reply from {self.url} has a non-text choices[0].message.content")
        usage = doc.get("usage") if isinstance(doc.get("usage"), dict) else {}
        reply = ChatReply(content, _count(usage.get("prompt_tokens")), _count(usage.get("completion_tokens")),
                          time.perf_counter() - start)
        self.calls += 1
        self.prompt_tokens += reply.prompt_tokens
        self.completion_tokens += reply.completion_tokens
        if self.transcript is not None:
            self.transcript.write({"round": round_no, "role": role, "model": self.model, "messages": messages,
                                   "reply": reply.content, "prompt_tokens": reply.prompt_tokens,
                                   "completion_tokens": reply.completion_tokens,
                                   "seconds": round(reply.seconds, 3)}, scrub=self.scrub)
        return reply

    def _post(self, data: bytes) -> dict:
        headers = {"Content-Type": "application/json", "Accept": "application/json"}
        if self._key:
            headers["Authorization"] = f"Bearer {self._key}"
        wait = self.backoff
        for attempt in range(self.retries + 1):
            request = urllib.request.Request(self.url, data=data, headers=headers, method="POST")
            try:
                with urllib.request.urlopen(request, timeout=self.timeout) as response:
                    raw = response.read()
            except urllib.error.HTTPError as err:
                detail = self.scrub(_one_line(err.read().decode("utf-8", "replace")))
                error = LLMError(f"HTTP {err.code} {err.reason} from {self.url}: {detail or '(no body)'}")
                retry = err.code == 429 or err.code >= 500
            except TimeoutError:  # socket.timeout is TimeoutError since 3.10
                error, retry = LLMError(f"no reply from {self.url} within {self.timeout:g} s"), True
            except urllib.error.URLError as err:
                reason = err.reason
                if isinstance(reason, TimeoutError):
                    error = LLMError(f"no reply from {self.url} within {self.timeout:g} s")
                else:
                    error = LLMError(f"cannot reach {self.url}: {_one_line(str(reason))}")
                retry = True
            except OSError as err:  # a connection reset mid-reply
                error, retry = LLMError(f"connection to {self.url} failed: {_one_line(str(err))}"), True
            else:
                return self._decode(raw)
            if not retry or attempt == self.retries:
                raise error
            time.sleep(wait)
            wait *= 2
        raise AssertionError("unreachable")

    def _decode(self, raw: bytes) -> dict:
        try:
            doc = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            raise LLMError(f"the reply from {self.url} is not JSON ({type(err).__name__}): "
                           f"{self.scrub(_one_line(raw.decode('utf-8', 'replace'), 120))}") from None
        if not isinstance(doc, dict):
            raise LLMError(f"the reply from {self.url} is JSON but not an object")
        if "error" in doc and "choices" not in doc:
            raise LLMError(f"the server at {self.url} answered with an error: "
                           f"{self.scrub(_one_line(json.dumps(doc['error'])))}")
        return doc


def _count(value: Any) -> int:
    return int(value) if isinstance(value, (int, float)) and not isinstance(value, bool) and value >= 0 else 0


class Transcript:
    """Every prompt and reply, one JSON object per line (appended and flushed as it happens)."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def write(self, entry: dict, scrub=None) -> None:
        line = json.dumps(entry, ensure_ascii=False)
        if scrub is not None:
            line = scrub(line)
        with open(self.path, "a", encoding="utf-8") as f:
            f.write(line + "\n")
