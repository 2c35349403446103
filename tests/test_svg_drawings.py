"""SVG drawings that used to be misread silently: clipping and masking (by attribute, ``style`` or style
sheet), stroke-only face shapes (by layer and by colour), and pages sized by one of width/height and the viewBox."""

import logging
import re

import numpy as np
import pytest

from gdfe._validation import GdfeError
from gdfe.fabrication import svg_masks

HEAD = '<svg xmlns="http://www.w3.org/2000/svg" {size}>\n'
SIZE = 'width="6mm" height="2mm" viewBox="0 0 6 2"'
BOTH = ('<g id="both"><rect x="0" y="0" width="2" height="2" fill="black"/>'
        '<rect x="4" y="0" width="2" height="2" fill="black"/></g>\n')
TOP = '<g id="top"><rect x="2" y="0" width="2" height="2" fill="black"/></g>\n'
CLIP_DEF = '<defs><clipPath id="c"><rect x="0" y="0" width="1" height="2"/></clipPath></defs>\n'


def drawing(tmp_path, body=BOTH + TOP, size=SIZE, name="d.svg"):
    path = tmp_path / name
    path.write_text(HEAD.format(size=size) + body + "</svg>\n")
    return path


def counts(m):
    return int(m.film.sum()), int(m.top.sum()), int(m.bottom.sum())


def same(a, b):
    return (np.array_equal(a.film, b.film) and np.array_equal(a.top, b.top)
            and np.array_equal(a.bottom, b.bottom) and np.allclose(a.origin, b.origin))


def test_the_plain_drawing(tmp_path):
    assert counts(svg_masks(drawing(tmp_path), 0.1)) == (1200, 1200, 800)


# --- clipping and masking --------------------------------------------------------------------------


@pytest.mark.parametrize("attr", ['clip-path="url(#c)"', 'style="fill:black; clip-path: url(#c)"', 'mask="url(#c)"',
                                  'style="mask:url(#c)"'])
def test_a_clipped_or_masked_face_shape_is_refused_naming_it(tmp_path, attr):
    top = f'<g id="top"><rect id="cut" x="2" y="0" width="2" height="2" fill="black" {attr}/></g>\n'
    with pytest.raises(GdfeError, match=r"d\.svg: element <rect id='cut'> \(line \d+\).*(clip|mask).*not applied"):
        svg_masks(drawing(tmp_path, CLIP_DEF + BOTH + top), 0.1)


def test_a_clipped_face_group_is_refused(tmp_path):
    top = '<g id="top" clip-path="url(#c)"><rect x="2" y="0" width="2" height="2" fill="black"/></g>\n'
    with pytest.raises(GdfeError, match=r"element <g id='top'>.*clip"):
        svg_masks(drawing(tmp_path, CLIP_DEF + BOTH + top), 0.1)


def test_a_clip_around_the_face_groups_is_refused(tmp_path):
    body = CLIP_DEF + '<g id="page" clip-path="url(#c)">' + BOTH + TOP + '</g>\n'
    with pytest.raises(GdfeError, match=r"element <g id='page'>.*clip.*face groups.*not applied"):
        svg_masks(drawing(tmp_path, body), 0.1)


def test_a_clip_in_colour_mode_is_refused_anywhere(tmp_path):
    body = CLIP_DEF + '<g clip-path="url(#c)"><rect x="0" y="0" width="6" height="2" fill="#ff0000"/></g>\n'
    with pytest.raises(GdfeError, match=r"element <g> \(line \d+\).*clip"):
        svg_masks(drawing(tmp_path, body), 0.1, by="colour")


def test_a_clip_on_a_cloned_element_is_refused(tmp_path):
    body = ('<defs><clipPath id="c"><rect width="1" height="2"/></clipPath>'
            '<rect id="r" x="2" y="0" width="2" height="2" fill="black" clip-path="url(#c)"/></defs>\n'
            + BOTH + '<g id="top"><use href="#r"/></g>\n')
    with pytest.raises(GdfeError, match=r"element <use> \(line \d+\).*<rect id='r'>.*clip"):
        svg_masks(drawing(tmp_path, body), 0.1)


def test_unused_clip_definitions_and_clip_none_are_accepted(tmp_path):
    top = '<g id="top"><rect x="2" y="0" width="2" height="2" fill="black" clip-path="none" style="mask: none"/></g>\n'
    outside = '<rect x="0" y="0" width="1" height="1" fill="none" clip-path="url(#c)"/>\n'
    m = svg_masks(drawing(tmp_path, CLIP_DEF + outside + BOTH + top), 0.1)
    assert counts(m) == (1200, 1200, 800)


# --- shapes without fill ---------------------------------------------------------------------------


def test_a_stroke_only_film_is_refused(tmp_path):
    film = ('<g id="film"><rect x="0.5" y="0" width="5" height="2" fill="none" stroke="black" '
            'stroke-width="0.05"/></g>\n')
    with pytest.raises(GdfeError, match=r"d\.svg: the film group's 1 shape\(s\) have no fill.*stroke.*fill the film"):
        svg_masks(drawing(tmp_path, BOTH + TOP + film), 0.1)


def test_a_stroke_only_face_shape_warns_and_is_left_out(tmp_path, caplog):
    plain = svg_masks(drawing(tmp_path, name="plain.svg"), 0.1)
    top = ('<g id="top"><rect x="2" y="0" width="2" height="2" fill="black"/>'
           '<rect id="outline" x="0" y="0" width="6" height="2" fill="none" stroke="black" stroke-width="0.05"/></g>\n')
    with caplog.at_level(logging.WARNING, logger="gdfe.fabrication.svg"):
        m = svg_masks(drawing(tmp_path, BOTH + top), 0.1)
    assert same(m, plain)
    text = " ".join(r.getMessage() for r in caplog.records if r.levelno == logging.WARNING)
    assert "no fill" in text and "<rect id='outline'>" in text and "left out" in text


def test_stroke_only_shapes_outside_face_groups_are_silent(tmp_path, caplog):
    guide = '<path d="M 0 1 H 6 V 1.5 Z" fill="none" stroke="blue" stroke-width="0.01"/>\n'
    with caplog.at_level(logging.WARNING, logger="gdfe.fabrication.svg"):
        m = svg_masks(drawing(tmp_path, guide + BOTH + TOP), 0.1)
    assert counts(m) == (1200, 1200, 800)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


# --- a page sized by one length and the viewBox -----------------------------------------------------


@pytest.mark.parametrize("size", ['width="6mm" viewBox="0 0 6 2"', 'height="2mm" viewBox="0 0 6 2"'])
def test_a_missing_page_length_follows_the_viewbox(tmp_path, size):
    full = svg_masks(drawing(tmp_path, name="full.svg"), 0.1)
    m = svg_masks(drawing(tmp_path, size=size), 0.1)
    assert same(m, full) and counts(m) == (1200, 1200, 800)


def test_a_page_with_width_only_and_no_viewbox_is_refused(tmp_path):
    with pytest.raises(GdfeError, match=r"d\.svg: expected a page size.*height=None"):
        svg_masks(drawing(tmp_path, size='width="6mm"'), 0.1)


# --- clipping and masking by a style sheet -----------------------------------------------------------


MASK_DEF = ('<defs><mask id="m"><rect x="0" y="0" width="1" height="2" fill="white"/></mask>'
            '<clipPath id="k"><rect x="0" y="0" width="1" height="2"/></clipPath></defs>\n')
CUT = '<g id="top"><rect id="cut" class="c" x="2" y="0" width="2" height="2" fill="black"/></g>\n'


def sheet(css):
    return f"<style>{css}</style>\n"


@pytest.mark.parametrize("css", [".c { clip-path: url(#k) }", "#cut {mask: url(#m)}", ".x, .c{mask-image:url(#m)}",
                                 "rect.c { clip-path: url(#k) !important }", "rect#cut.c { mask: url(#m) }"])
def test_a_face_shape_clipped_or_masked_by_the_style_sheet_is_refused_naming_it(tmp_path, css):
    body = sheet(css) + MASK_DEF + BOTH + CUT
    with pytest.raises(GdfeError, match=r"d\.svg: element <rect id='cut'> \(line \d+\): (clip|mask).*style sheet.*"
                                        r"not applied"):
        svg_masks(drawing(tmp_path, body), 0.1)


def test_a_style_sheet_clipping_every_rect_is_refused(tmp_path):
    body = MASK_DEF + BOTH + TOP + sheet("rect { clip-path: url(#k) }")  # a sheet applies wherever it stands
    with pytest.raises(GdfeError, match=r"element <rect> \(line \d+\): clip-path='url\(#k\)'.*style sheet.*rect"):
        svg_masks(drawing(tmp_path, body), 0.1)


def test_a_face_group_clipped_by_the_style_sheet_is_refused(tmp_path):
    top = '<g id="top" class="layer"><rect x="2" y="0" width="2" height="2" fill="black"/></g>\n'
    with pytest.raises(GdfeError, match=r"element <g id='top'>.*clip.*style sheet"):
        svg_masks(drawing(tmp_path, sheet(".layer { clip-path: url(#k) }") + MASK_DEF + BOTH + top), 0.1)


def test_a_style_sheet_mask_around_the_face_groups_is_refused(tmp_path):
    body = sheet("g.page { mask: url(#m) }") + MASK_DEF + '<g class="page">' + BOTH + TOP + '</g>\n'
    with pytest.raises(GdfeError, match=r"element <g> \(line \d+\): mask.*style sheet.*face groups.*not applied"):
        svg_masks(drawing(tmp_path, body), 0.1)


def test_a_style_sheet_clip_in_colour_mode_is_refused_anywhere(tmp_path):
    body = (sheet(".c { clip-path: url(#k) }") + MASK_DEF
            + '<g class="c"><rect x="0" y="0" width="6" height="2" fill="#ff0000"/></g>\n')
    with pytest.raises(GdfeError, match=r"element <g> \(line \d+\).*clip.*style sheet"):
        svg_masks(drawing(tmp_path, body), 0.1, by="colour")


def test_a_style_sheet_clip_on_a_cloned_element_is_refused(tmp_path):
    body = (sheet("#r { clip-path: url(#k) }") + MASK_DEF
            + '<defs><rect id="r" x="2" y="0" width="2" height="2" fill="black"/></defs>\n'
            + BOTH + '<g id="top"><use href="#r"/></g>\n')
    with pytest.raises(GdfeError, match=r"element <use> \(line \d+\).*<rect id='r'>.*clip.*style sheet"):
        svg_masks(drawing(tmp_path, body), 0.1)


@pytest.mark.parametrize("css", ["g .c { clip-path: url(#k) }", "#top > rect { mask: url(#m) }",
                                 "rect[id=cut] { mask-image: url(#m) }", "rect:first-child { clip-path: url(#k) }",
                                 "@media print { svg|rect { mask: url(#m) } }"])
def test_a_style_sheet_clip_by_a_selector_not_resolved_is_refused(tmp_path, css):
    with pytest.raises(GdfeError, match=r"d\.svg: element <style> \(line 2\): the style sheet clips or masks.*"
                                        r"not resolved.*release"):
        svg_masks(drawing(tmp_path, sheet(css) + MASK_DEF + BOTH + CUT), 0.1)


def test_mask_image_in_the_style_attribute_is_refused(tmp_path):
    top = '<g id="top"><rect id="cut" x="2" y="0" width="2" height="2" style="fill:black; mask-image: url(#m)"/></g>\n'
    with pytest.raises(GdfeError, match=r"element <rect id='cut'> \(line \d+\): mask-image='url\(#m\)'.*not applied"):
        svg_masks(drawing(tmp_path, MASK_DEF + BOTH + top), 0.1)


def test_ordinary_style_sheets_are_read(tmp_path, caplog):
    plain = svg_masks(drawing(tmp_path, name="plain.svg"), 0.1)
    css = (".fill-1 { fill: #000000 } .none { fill: none; stroke: #999999; clip-path: none; mask-image: none } "
           "g > rect { stroke-width: 0.01 } .guide { clip-path: url(#k) } rect[id=x] { stroke: black }")
    body = (sheet(css) + MASK_DEF + '<rect class="guide none" x="0" y="0" width="6" height="1"/>\n'
            '<g id="both"><rect class="fill-1" x="0" y="0" width="2" height="2"/>'
            '<rect class="fill-1" x="4" y="0" width="2" height="2"/></g>\n'
            '<g id="top"><rect class="fill-1" x="2" y="0" width="2" height="2"/></g>\n')
    with caplog.at_level(logging.WARNING, logger="gdfe.fabrication.svg"):
        assert same(svg_masks(drawing(tmp_path, body), 0.1), plain)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_an_illustrator_style_sheet_is_read_by_colour(tmp_path, caplog):
    plain = svg_masks(drawing(tmp_path, name="plain.svg"), 0.1)
    css = ".cls-1{fill:#000;}.cls-2{fill:red;}.cls-3{fill:none;stroke:#999;stroke-miterlimit:10;}"
    body = (f'<defs>{sheet(css)}</defs>'
            '<rect class="cls-1" x="0" y="0" width="2" height="2"/>'
            '<rect class="cls-1" x="4" y="0" width="2" height="2"/>'
            '<rect class="cls-2" x="2" y="0" width="2" height="2"/>'
            '<rect class="cls-3" x="0" y="0" width="6" height="2"/>\n')
    with caplog.at_level(logging.WARNING, logger="gdfe.fabrication.svg"):
        assert same(svg_masks(drawing(tmp_path, body), 0.1, by="colour"), plain)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


# --- by colour: shapes without fill stroked in a face colour ----------------------------------------


COLOURED = ('<rect x="0" y="0" width="2" height="2" fill="black"/>'
            '<rect x="4" y="0" width="2" height="2" fill="black"/>'
            '<rect x="2" y="0" width="2" height="2" fill="red"/>\n')


def test_a_stroke_in_a_face_colour_without_fill_warns_by_colour(tmp_path, caplog):
    plain = svg_masks(drawing(tmp_path, COLOURED, name="plain.svg"), 0.1, by="colour")
    body = (sheet(".coat { fill: none; stroke: #0000ff }") + COLOURED
            + '<rect id="outline" x="0" y="0" width="6" height="2" fill="none" stroke="red" stroke-width="0.05"/>'
            + '<path id="edge" class="coat" d="M 0 0 H 6 V 2 Z" stroke-width="0.05"/>\n')
    with caplog.at_level(logging.WARNING, logger="gdfe.fabrication.svg"):
        m = svg_masks(drawing(tmp_path, body), 0.1, by="colour")
    assert same(m, plain)
    text = " ".join(r.getMessage() for r in caplog.records if r.levelno == logging.WARNING)
    assert "2 shape(s)" in text and "no fill" in text and "left out" in text
    assert re.search(r"<rect id='outline'> \(line \d+\): stroke #ff0000, the top face's colour", text)
    assert re.search(r"<path id='edge'> \(line \d+\): stroke #0000ff, the bottom face's colour", text)


def test_strokes_in_other_colours_are_silent_by_colour(tmp_path, caplog):
    guide = '<path d="M 0 1 H 6 V 1.5 Z" fill="none" stroke="#999999" stroke-width="0.01"/>\n'
    with caplog.at_level(logging.WARNING, logger="gdfe.fabrication.svg"):
        m = svg_masks(drawing(tmp_path, COLOURED + guide), 0.1, by="colour")
    assert counts(m) == (1200, 1200, 800)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_a_film_drawn_only_as_a_stroke_is_refused_by_colour(tmp_path):
    film = '<rect id="f" x="0.5" y="0" width="5" height="2" fill="none" stroke="#00ff00" stroke-width="0.05"/>\n'
    with pytest.raises(GdfeError, match=r"d\.svg: 1 shape\(s\) in the film's colour have no fill.*<rect id='f'>.*"
                                        r"fill the film"):
        svg_masks(drawing(tmp_path, COLOURED + film), 0.1, by="colour")
