"""plotting.save_figure: a picture is written whole or not at all, and the figure is closed either way."""

import pytest

from twinsense.plotting import pyplot, save_figure


def test_a_failed_save_leaves_no_partial_file_and_closes_the_figure(tmp_path, monkeypatch):
    plt = pyplot()
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    real = fig.savefig

    def dies_halfway(fname, **kw):
        real(fname, **kw)  # the temporary file is written, then the save fails (a full disk, a bad backend)
        raise OSError("disk full")

    monkeypatch.setattr(fig, "savefig", dies_halfway)
    (tmp_path / "keep.png").write_bytes(b"old")
    with pytest.raises(OSError, match="disk full"):
        save_figure(fig, tmp_path / "keep.png")
    # Before: the hidden ".keep.png.tmp.png" stayed behind and the figure stayed open.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.png"]
    assert (tmp_path / "keep.png").read_bytes() == b"old"
    assert not plt.fignum_exists(fig.number)


def test_a_saved_figure_is_whole_and_closed(tmp_path):
    plt = pyplot()
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    out = save_figure(fig, tmp_path / "sub" / "a.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"  # the PNG signature
    assert sorted(p.name for p in (tmp_path / "sub").iterdir()) == ["a.png"]
    assert not plt.fignum_exists(fig.number)
