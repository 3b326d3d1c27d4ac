"""The keep-alive of a Livox link as a clock-driven state machine (no sockets): when
the next keep-alive is due, which went unanswered, and when the link counts as dead.

With period T and time-out τ (the SDK 1 heartbeat: T = 1 s, τ = 3 s), a keep-alive is
due at t₀, t₀ + T, …; one still unanswered when the next is sent counts as missed; the
link is dead once t − t_answer > τ, t_answer the last answer (or the connection)."""

from __future__ import annotations

__all__ = ["KeepAlive"]


class KeepAlive:
    """Counters: ``sent``, ``missed``.  All times are monotonic seconds given by the
    caller."""

    def __init__(self, period_s: float, timeout_s: float) -> None:
        self.period_s = period_s
        self.timeout_s = timeout_s
        self.sent = 0
        self.missed = 0
        self.last_answer = 0.0
        self.pending = False
        self.next_due = 0.0

    def expired(self, now: float) -> bool:
        """No answer for more than the time-out: the link is dead."""
        return now - self.last_answer > self.timeout_s

    def due(self, now: float) -> bool:
        return now >= self.next_due

    def was_sent(self, now: float, ok: bool) -> None:
        """A keep-alive went out at ``now`` (``ok``: the send succeeded); the previous
        one, if still unanswered, is missed; the next is due a period later."""
        if self.pending:
            self.missed += 1
        if ok:
            self.sent += 1
            self.pending = True
        self.next_due = now + self.period_s

    def answered(self, now: float) -> None:
        self.last_answer = now
        self.pending = False
