"""Ctrl-C held back over compiled calls (localizer.interrupts), in detect_targets."""
import math
import signal
import threading

import numpy as np
import pytest

import localizer.detect as detect_module
from localizer import Camera, detect_targets
from localizer.interrupts import deferred_interrupt
from localizer.tools.synthetic import pose_at_column, render_frame


@pytest.fixture(autouse=True)
def default_sigint():
    """Each test starts and ends with Python's own SIGINT handler."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler, "the block left its handler in place"
    signal.signal(signal.SIGINT, before)


def test_a_sigint_in_the_block_is_raised_when_it_ends():
    done = []
    with pytest.raises(KeyboardInterrupt):
        with deferred_interrupt():
            signal.raise_signal(signal.SIGINT)
            done.append("after the signal")
    assert done == ["after the signal"]


def test_nested_blocks_raise_once_at_the_outermost_end():
    done = []
    with pytest.raises(KeyboardInterrupt):
        with deferred_interrupt():
            with deferred_interrupt():
                signal.raise_signal(signal.SIGINT)
                signal.raise_signal(signal.SIGINT)
            done.append("inner block left")
            assert signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    assert done == ["inner block left"]


def test_no_signal_no_interrupt_and_the_handler_is_back():
    with deferred_interrupt():
        assert signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_the_blocks_own_error_becomes_the_interrupts_context():
    with pytest.raises(KeyboardInterrupt) as info:
        with deferred_interrupt():
            signal.raise_signal(signal.SIGINT)
            raise ZeroDivisionError("in the block")
    assert isinstance(info.value.__context__, ZeroDivisionError)


def test_a_programs_own_handler_is_called_once_after_the_block():
    calls = []
    signal.signal(signal.SIGINT, lambda signum, frame: calls.append(signum))
    try:
        with deferred_interrupt():
            signal.raise_signal(signal.SIGINT)
            signal.raise_signal(signal.SIGINT)
            assert calls == []
        assert calls == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def test_an_ignored_sigint_stays_ignored():
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with deferred_interrupt():
            assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
            signal.raise_signal(signal.SIGINT)
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def test_outside_the_main_thread_the_block_holds_nothing():
    seen = []

    def worker():
        with deferred_interrupt():
            seen.append(signal.getsignal(signal.SIGINT))

    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert seen == [signal.default_int_handler]


def test_detect_targets_finishes_the_frame_before_a_ctrl_c_is_raised(monkeypatch):
    """A SIGINT arriving inside the detection (as one does while a compiled kernel returns)
    is raised after the call's work; without the hold it is raised where it arrives."""
    cam = Camera.thesis(16)
    pose = pose_at_column(cam, 3.0, math.radians(20), cam.cx, 0.03)
    img = render_frame(cam, pose, blur=0.6, noise=1.0, rng=np.random.default_rng(3))
    assert len(detect_targets(img, cam)) == 1
    inner, found = detect_module._detect, []

    def interrupted(*args, **kwargs):
        signal.raise_signal(signal.SIGINT)
        found.extend(inner(*args, **kwargs))
        return found

    monkeypatch.setattr(detect_module, "_detect", interrupted)
    with pytest.raises(KeyboardInterrupt):
        detect_targets(img, cam)
    assert len(found) == 1
