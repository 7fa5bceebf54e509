"""Add all photos (the modelling screen's button beside Add photo): every image file in the project's
folder and the folders inside it that the project lacks, added in one undoable edit, in path order;
photos already in the project, hidden files and files that are no image left out (the last named)."""

from __future__ import annotations

from edit_scene import PHOTOS, make_plan, photo_file

from vebuild.edit.session import EditSession


def test_every_image_of_the_folder_is_added_in_one_undoable_edit(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    assert [f.stem for f in s.folder_photos()] == list(PHOTOS)
    assert s.add_folder_photos() == list(PHOTOS)
    assert s.photo_ids == list(PHOTOS)
    assert {s.photo(p)["file"] for p in PHOTOS} == {photo_file(plan, p).relative_to(plan.folder).as_posix()
                                                    for p in PHOTOS}
    assert all(len(s.photo(p)["sha256"]) == 64 for p in PHOTOS)
    s.undo()
    assert s.photo_ids == []
    s.redo()
    assert s.photo_ids == list(PHOTOS)
    # Again: nothing left to add, and it says so.
    assert s.folder_photos() == [] and s.add_folder_photos() == []
    assert s.photo_ids == list(PHOTOS)


def test_photos_already_added_hidden_files_and_non_images_are_left_out(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    s.add_photo(photo_file(plan, "p3"))
    (plan.folder / ".thumbs").mkdir()
    (plan.folder / ".thumbs" / "p9.jpg").write_bytes(photo_file(plan, "p1").read_bytes())
    (plan.folder / "notes.txt").write_text("not a photo")
    (plan.folder / "broken.jpg").write_bytes(b"not an image")
    (plan.folder / "more").mkdir()
    (plan.folder / "more" / "p1.png").write_bytes(photo_file(plan, "p1").read_bytes())
    added = s.add_folder_photos()
    # In path order more/p1.png comes first and takes the id p1; photos/p1.jpg's is made unique.
    assert added == ["p1", "p1-2", "p4", "p5"]
    assert s.photo("p1")["file"] == "more/p1.png" and s.photo("p1-2")["file"] == "photos/p1.jpg"
    assert "broken.jpg" in s.messages[-1] and "p3" not in added
    assert sorted(s.photo_ids) == sorted(["p3", *added])


def test_camera_raw_files_are_offered_too(tmp_path):
    """Forensic photographers shoot RAW: a .NEF or .dng in the folder is one of its photos (one
    that is not a RAW file after all is named and left out, as any other)."""
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    (plan.folder / "raw").mkdir()
    (plan.folder / "raw" / "scene.NEF").write_bytes(b"not a raw file")
    assert plan.folder / "raw" / "scene.NEF" in s.folder_photos()
    added = s.add_folder_photos()
    assert added == list(PHOTOS) and "raw/scene.NEF" in s.messages[-1]
