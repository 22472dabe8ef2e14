"""drivers.gc_freeze: the collector leaves alone what existed when a streaming section began."""

import gc
import weakref

from drivers.gc_freeze import GcPauses, frozen_gc


class _Node:
    def __init__(self):
        self.other = None


def _cycle():
    """Two objects that only reference each other (once dropped, garbage that only the cyclic
    collector frees), and a weak reference that tells whether they were freed."""
    a, b = _Node(), _Node()
    a.other, b.other = b, a
    return a, weakref.ref(a)


def test_frozen_objects_are_not_collected_until_the_outermost_section_ends():
    gc.collect()
    assert gc.get_freeze_count() == 0
    before, before_ref = _cycle()
    with frozen_gc():
        assert gc.get_freeze_count() > 0
        inner, inner_ref = _cycle()
        with frozen_gc():   # nested: freezes ``inner`` too, unfreezes nothing on exit
            del before, inner
            gc.collect()
            assert before_ref() is not None and inner_ref() is not None   # frozen: not walked
        gc.collect()
        assert gc.get_freeze_count() > 0 and before_ref() is not None and inner_ref() is not None
        fresh, fresh_ref = _cycle()
        del fresh
        gc.collect()
        assert fresh_ref() is None            # created inside the section: collected as usual
    assert gc.get_freeze_count() == 0
    gc.collect()
    assert before_ref() is None and inner_ref() is None   # freed once the outermost section ended


def test_gc_pauses_times_each_collection_by_generation():
    with GcPauses() as pauses:
        gc.collect(0)
        gc.collect(2)
    assert pauses.generations[-2:] == [0, 2]
    assert len(pauses.durations) == len(pauses.generations) and all(d >= 0 for d in pauses.durations)
    assert pauses.longest == max(pauses.durations)
    assert pauses._callback not in gc.callbacks
