import threading

from rough_viewer.app.controller import LatestWorker


def test_latest_request_wins_and_errors_do_not_kill_the_worker():
    seen, errors = [], []
    gate = threading.Event()

    def handler(req, is_stale):
        if req == "block":
            gate.wait(5)
            seen.append(("block", is_stale()))
            return
        if req == "boom":
            raise RuntimeError("boom")
        seen.append(req)

    w = LatestWorker(handler, on_error=errors.append)
    w.submit("block")
    while not w.busy or not w._busy:  # wait until the worker holds "block"
        pass
    for i in range(20):  # a slider drag while busy
        w.submit(i)
    gate.set()
    assert w.wait_idle(5)
    assert seen == [("block", True), 19]
    w.submit("boom")
    assert w.wait_idle(5)
    w.submit("after")
    assert w.wait_idle(5)
    assert [str(e) for e in errors] == ["boom"] and seen[-1] == "after"
    w.stop()


def test_idle_job_runs_between_requests_until_done():
    import time

    done = []

    def idle(is_stale):
        if len(done) >= 3:
            return False
        done.append(is_stale())
        return True

    w = LatestWorker(lambda req, is_stale: None, idle=idle)
    w.submit("go")
    end = time.time() + 5
    while len(done) < 3 and time.time() < end:
        time.sleep(0.01)
    assert done == [False, False, False]
    time.sleep(0.05)
    assert len(done) == 3  # stopped asking once it reported no more work
    w.stop()
