"""A progress bar for long host loops: tqdm when installed, else one line on stderr."""
from __future__ import annotations

import sys
import time


class Progress:
    """``update(n, **postfix)`` after each unit of work; ``close()`` at the end. A postfix
    item stays shown until updated. ``enabled=False`` prints nothing."""

    def __init__(self, total: int, unit: str, enabled: bool = True):
        self.total, self.unit, self.enabled = total, unit, enabled
        self.done, self.start, self._bar, self.postfix = 0, time.perf_counter(), None, {}
        if enabled:
            try:
                from tqdm.auto import tqdm
                self._bar = tqdm(total=total, unit=unit, unit_scale=True, dynamic_ncols=True)
            except ImportError:
                pass

    def update(self, n: int, **postfix) -> None:
        self.done += n
        postfix = self.postfix = {**self.postfix, **postfix}
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.set_postfix(postfix, refresh=False)
            self._bar.update(n)
            return
        rate = self.done / max(time.perf_counter() - self.start, 1e-9)
        filled = int(30 * self.done / max(self.total, 1))
        extra = "".join(f", {k} {v}" for k, v in postfix.items())
        speed = f"{rate:,.0f}" if rate >= 10 else f"{rate:.2g}"  # a slow unit: a fit's iteration
        sys.stderr.write(f"\r[{'#' * filled}{'.' * (30 - filled)}] {self.done}/{self.total} {self.unit} "
                         f"({speed} {self.unit}/s{extra})")
        sys.stderr.flush()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
        elif self.enabled:
            sys.stderr.write("\n")
