"""framework/esper_adapter.py: the only reader of esper's internals, checked against esper itself."""
import esper
import pytest

from driftframe.framework import esper_adapter as ea


class A:
    pass


class B:
    pass


@pytest.fixture
def ctx():
    """A fresh esper world context, current during the test, deleted after."""
    before = ea.current()
    ea.switch("adapter-test")
    yield "adapter-test"
    ea.delete("adapter-test")
    ea.switch(before)


def test_every_internal_it_uses_exists_in_this_esper():
    ea.check()
    assert all(hasattr(esper, n) for n in ea.USED)


def test_check_names_what_is_missing(monkeypatch):
    monkeypatch.delattr(esper, "_cache_dirty")
    with pytest.raises(ImportError, match=r"esper .* lacks _cache_dirty"):
        ea.check()


def test_switch_exists_and_delete_manage_world_contexts(ctx):
    assert ea.current() == ctx and ea.exists(ctx)
    e = esper.create_entity(A())
    ea.switch("adapter-other")
    assert ea.current() == "adapter-other" and not esper.entity_exists(e)
    ea.delete("adapter-other")
    assert not ea.exists("adapter-other") and ea.current() == "default"
    ea.switch(ctx)
    assert esper.entity_exists(e)                   # the first context kept its entity


def test_the_probe_sees_every_structural_change_and_nothing_else(ctx):
    e = esper.create_entity(A())
    p = ea.probe()
    assert ea.structure_unchanged(p, ctx)
    esper.get_components(A)                          # a query is not a change
    esper.component_for_entity(e, A)
    assert ea.structure_unchanged(p, ctx)
    for change in (lambda: esper.add_component(e, B()), lambda: esper.remove_component(e, B),
                   lambda: esper.create_entity(A()), lambda: esper.delete_entity(e, immediate=True)):
        p = ea.probe()
        change()
        assert not ea.structure_unchanged(p, ctx)
        assert ea.structure_unchanged(ea.probe(), ctx)
    assert not ea.structure_unchanged(ea.probe(), "another-name")    # another context is current


def test_component_types_holders_and_live_entities(ctx):
    e1, e2 = esper.create_entity(A()), esper.create_entity(A(), B())
    assert set(ea.component_types()) == {A, B}
    assert ea.holders(A) == {e1, e2} and ea.holders(B) == {e2} and ea.holders(int) == set()
    esper.delete_entity(e1)                          # pending: not live, though esper still holds it
    assert ea.live_entities() == [e2]


def test_next_entity_reads_the_counter_without_taking_an_id(ctx):
    e = esper.create_entity()
    assert ea.next_entity() == e + 1 == ea.next_entity()
    assert esper.create_entity() == e + 1


def test_create_with_ids_and_delete_all(ctx):
    esper.create_entity(A())
    ea.delete_all_entities()
    assert ea.live_entities() == [] and ea.holders(A) == set()
    a, b = A(), B()
    ea.create_with_ids([(7, [a]), (3, [b])], next_id=20)
    assert ea.live_entities() == [3, 7]
    assert esper.component_for_entity(7, A) is a and esper.component_for_entity(3, B) is b
    assert ea.next_entity() == 20 and esper.create_entity() == 20


def test_no_other_module_of_driftframe_reads_esper_internals():
    """The boundary holds: esper's private names (and its world switching) appear only in the adapter."""
    import pathlib
    import re

    root = pathlib.Path(ea.__file__).resolve().parent.parent
    pattern = re.compile(r"esper\.(_\w+|switch_world|list_worlds|delete_world|current_world)\b")
    offenders = []
    for folder in ("framework", "systems", "components", "demos", "driftframe"):
        for path in (root / folder).rglob("*.py"):
            if path.name == "esper_adapter.py":
                continue
            for k, line in enumerate(path.read_text().splitlines(), 1):
                if pattern.search(line):
                    offenders.append(f"{folder}/{path.relative_to(root / folder)}:{k}")
    assert offenders == []
