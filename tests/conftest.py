"""Session hooks of the test suite."""
from __future__ import annotations


def pytest_sessionfinish(session, exitstatus):
    """Leave no compiler running: the solves of the suite start background builds into the compile cache
    (transcription.compile.codegen's interpreted-first policy).  Wait a little for those still under way (the cache is then
    complete for the next run), then end the rest (a cold cache's last -O1 builds can take minutes at low priority;
    they start again on the next use), so that no builder and no ``.building`` lock is left behind."""
    from se3ocp.transcription.compile import codegen

    waited = codegen.settle(20.0)
    stopped = codegen.stop()
    if waited > 1.0 or stopped:
        session.config.get_terminal_writer().line(
            f"waited {waited:.0f} s for background compiles to finish; stopped {stopped}")
