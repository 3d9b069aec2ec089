"""Session hooks of the test suite."""
from __future__ import annotations


def pytest_sessionfinish(session, exitstatus):
    """Leave no compiler running: the solves of the suite start background builds into the compile cache
    (transcription.codegen's interpreted-first policy); wait for those still under way, so that the suite ends with
    the cache complete and no ``.building`` lock behind (bounded: a build older than codegen.BACKGROUND_TIMEOUT is
    taken for dead anyway)."""
    from se3ocp.transcription import codegen

    waited = codegen.settle(600.0)
    if waited > 1.0:
        session.config.get_terminal_writer().line(f"waited {waited:.0f} s for background compiles to finish")
