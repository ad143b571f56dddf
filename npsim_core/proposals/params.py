"""Thresholds of the light proposers (docs/proposals.md)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ProposalParams:
    """Every threshold of :func:`npsim_core.proposals.propose_lights`.

    Lengths are metres unless the name ends in ``_px`` (pixels); ratios are unitless;
    confidences lie in [0, 1].
    """

    #: The confidence callers keep by default (``LightProposals.above(params.min_confidence)``).
    min_confidence: float = 0.5
    #: Categories to propose (any subset of traffic_lights, street_lamps, vehicles, windows, ads).
    categories: tuple[str, ...] = ("traffic_lights", "street_lamps", "vehicles", "windows", "ads")
    #: Camera height above the ground (m) and downward pitch (rad), for heights from depth
    #: (``propose_for_scene`` takes them from the scene).
    camera_height_m: float = 1.22
    camera_pitch_rad: float = 0.038

    # --- traffic lights
    #: Smallest traffic-light component (pixels) that is split into lamp cells.
    tl_min_area_px: int = 12
    #: Lamp side as a fraction of the cell's shorter side (a 0.24 m lens in a 0.33 m cell is ~0.72).
    tl_lamp_fraction: float = 0.72
    #: The lamp squares are moved onto the lenses by up to this fraction of their side (at least 1 px):
    #: an off-axis housing's label holds its side and underside (traffic_lights.lens_cells).
    tl_lens_reach: float = 0.25
    #: Housing aspect (long / short side) above which the housing holds three cells in a line.
    tl_min_aspect: float = 1.6
    #: A lamp cell whose brightest linear channel (mean) is this many times every other cell's is lit
    #: by day (the signal's state).
    tl_lit_ratio: float = 2.5
    #: With depth, a vertical housing at most this tall (m) is a pedestrian signal (two lamps).
    tl_pedestrian_max_h_m: float = 0.85

    # --- street lamps
    #: Smallest pole component (pixels) examined for a lamp head.
    pole_min_area_px: int = 6
    #: Lamp heads are looked for within this distance (m) below the component's top.
    lamp_head_band_m: float = 0.55
    #: A pole whose top is at least this high (m above the ground) carries a high (HT) lamp, else a low one.
    lamp_high_min_m: float = 6.0
    #: Poles lower than this (m) carry no street lamp (bollards, sign posts, traffic-light poles).
    lamp_min_height_m: float = 3.2
    #: An arm reaching at least this far (m) from the trunk marks a street lamp at its end.
    lamp_min_arm_m: float = 0.6
    #: A pole top at least this many times wider than the trunk is a lantern.
    lamp_lantern_min_widening: float = 1.6
    #: A pole top without an arm takes a speck of pole (``lamp_speck_min_px`` pixels up to
    #: ``pole_min_area_px``) at its top ``lamp_min_arm_m`` to this far (m) sideways as its head (far
    #: away the arm is under a pixel and the labels lose it).
    lamp_max_arm_m: float = 2.6
    lamp_speck_min_px: int = 2
    #: A trunk whose top the labels lost takes as its arm a speck of pole starting at its column up to
    #: this far (m) above its top (street_lamps._lost_top).
    lamp_lost_top_m: float = 2.5
    #: Confidence of an arm's head (and of a far head that is a speck beside its pole's top): an arm
    #: reaching out from a pole taller than ``lamp_min_height_m`` holds a luminaire (docs/proposals.md,
    #: eleventh pass: 88-95 % of them match their lamp at IoU >= 0.5).
    lamp_arm_conf: float = 0.9

    # --- vehicles
    #: Smallest vehicle instance (pixels) that gets lamps and panes: a car of 40 px (8 x 5) still shows a
    #: rear window of a few pixels (docs/proposals.md, "Eleventh pass: vehicle lamps").
    vehicle_min_area_px: int = 40
    #: Without instance ids, a vehicle component is split where depth jumps by more than this
    #: fraction of the nearer depth across ~W/256 pixels (cars in a row touch in the image, not in depth).
    vehicle_split_jump: float = 0.15
    #: Find the end face from depth: the columns within max(tol_m, tol_rel x depth) of the densest
    #: depth among the nearer columns (metres, fraction).
    vehicle_face_from_depth: bool = True
    vehicle_face_tol_m: float = 0.3
    vehicle_face_tol_rel: float = 0.02
    #: A vehicle's end face lies at its nearer end only where its two ends' predicted depths differ by more
    #: than max(``vehicle_face_tol_m``, this fraction of depth); else at the end away from the principal
    #: point, as for a vehicle parallel to the street (a far car's side face blurs into its end face in
    #: predicted depth: ends 1-2 % apart; docs/proposals.md, "Fifteenth pass: vehicle lamps at 512x256").
    vehicle_side_tie_rel: float = 0.025
    #: Width (m) of a car and of a truck or bus: the extent of the end face the camera sees.
    vehicle_width_m: tuple[float, float] = (1.8, 2.5)
    #: Lamp box on the end face without depth, as fractions of the body face: rows from the body top,
    #: columns in from each side.
    vehicle_lamp_rows: tuple[float, float] = (0.12, 0.42)
    vehicle_lamp_cols: tuple[float, float] = (0.04, 0.22)
    #: The same in metres, with depth.
    vehicle_lamp_rows_m: tuple[float, float] = (0.06, 0.23)
    vehicle_lamp_cols_m: tuple[float, float] = (0.07, 0.40)
    #: Plate zone (no lamp): this far either side of the end face's axis, in metres with depth, as a
    #: fraction of the face width without (a 0.52 m plate plus margin).
    vehicle_plate_half_m: float = 0.3
    vehicle_plate_half_frac: float = 0.17
    #: A vehicle is driving (moving_* lamps) when it is at most this far (m) sideways from the camera ...
    vehicle_lane_max_m: float = 2.9
    #: ... and no kerb-side label (sidewalk, parking, building...) lies within this distance (m) of it.
    vehicle_kerb_m: float = 1.0
    #: Share of a lamp box that must be on the vehicle's silhouette (else hidden: not proposed).
    vehicle_lamp_min_visible: float = 0.6
    #: A lamp snapped to the pixels 40 levels off the paint also takes the pixels of its 1-px rim departing by
    #: at least this share of the lamp's own departure (its 90th percentile): part lamp, part paint (its edge's
    #: antialiasing); see ``vehicles._with_rim``.
    vehicle_lamp_rim_share: float = 0.4
    #: A lamp under 3 px tall is not snapped to off-paint pixels none of whose pixel centres lies this far (m)
    #: below the body's top edge (a lamp's top is 0.07 m below it; above that, the body's top edge, the deck
    #: or the cabin seam, stands out by day); 0: off (``vehicles._lamp_pair``).
    vehicle_small_lamp_top_m: float = 0.07
    #: A lamp beside the cut whose pixels over the sliver's 40 levels are fewer rows than a lamp's (a far
    #: lamp's blur) is the connected pixels departing from the paint by at least this share of its peak
    #: departure (a fraction of its 8-bit levels), less the bled rim; 0 or 1: off (``vehicles._sliver_grown``).
    vehicle_sliver_grow_share: float = 0.5
    #: ... on vehicles whose whole lamp (0.15 m) is under this many pixels tall (a taller lamp's rows are
    #: clear of the 3x3 blur: a single row over 40 levels there is a seam's or an edge's).
    vehicle_sliver_grow_max_px: float = 4.0
    #: A lamp box laid out by geometry alone (snapped to nothing) whose rows miss the sliver found beside the
    #: cut, the sliver's columns within the box's and this many pixels either way, is that lamp rows off (the
    #: face's top under the car in front): the sliver replaces it; -1: off (``vehicles._sliver_under_box``).
    vehicle_sliver_box_tol_px: int = 1
    #: A lamp 1 px across at the cut, blended with the car in front (``vehicles._sliver_blend``): the cut column
    #: departs from its own colour over a run of rows by more than this many 8-bit levels (per row and on
    #: average) beyond the columns two away either side; 0: off (docs/proposals.md "Nineteenth pass: vehicle
    #: lamps").
    vehicle_sliver_blend_levels: float = 6.0
    #: ... the run's top and bottom (m below the end face's top row): the lamp rows, not the body's top edge.
    vehicle_sliver_blend_rows_m: tuple[float, float] = (0.05, 0.32)
    #: ... the occluder's last column, the cut column and the car's next shift alike over the run: the mean
    #: shift (8-bit levels, its length over RGB) within these bounds, ...
    vehicle_sliver_blend_shift: tuple[float, float] = (8.0, 40.0)
    #: ... and each column's shift within this share of the mean's length from the mean.
    vehicle_sliver_blend_spread: float = 0.55
    #: A vehicle cut by the car in front whose image shows no lamp there gets its inner lamp's visible part
    #: laid out from the silhouette's other end, the side face's far end: the end face's inner edge where a
    #: side face this long (m) would end (``vehicles._cut_strip_lamp``); 0: off.
    vehicle_cut_strip_length_m: float = 4.3
    #: ... where the body's top edge at the side face's far end lies this high (m above the ground) ...
    vehicle_cut_strip_top_m: tuple[float, float] = (0.75, 1.05)
    #: ... and the lamp's inner end lies past the cut column's pixel centre by at least the larger of this many
    #: pixels and this share of the side face's width (its length's spread moves the inner edge by as much).
    vehicle_cut_strip_margin: tuple[float, float] = (0.65, 0.1)
    #: ... and such a lamp alone on a vehicle right of the principal point is a rear lamp, whatever its colour (a
    #: blend of the occluder's and the paint's: a parked row on the right is parked with the traffic and seen
    #: from behind; on the left either way, so its colour decides).
    vehicle_cut_strip_rear_right: bool = True
    #: A lamp box's snapped blob reaching the image's left or right border and darker than the paint by more
    #: than this many 8-bit levels in every channel is no lamp (a near car's dark end trim or glass the frame
    #: cuts; a lamp by day is red or brighter): the box is laid out as unsnapped; 0: off
    #: (``vehicles._dark_at_border``; docs/proposals.md "Eighteenth pass: vehicle lamps held out").
    vehicle_border_dark_levels: float = 20.0
    #: A lamp under ``SMALL_LAMP_PX`` tall is not snapped to a blob lying wholly in the silhouette's last column
    #: beside background (the street's colour bled into the car's edge; ``vehicles._edge_bleed``;
    #: docs/proposals.md "Eighteenth pass: vehicle lamps held out"); False: off.
    vehicle_small_lamp_edge_bleed: bool = True
    #: A vehicle silhouette narrower than this share of the end face's width (``vehicle_width_m`` at its
    #: depth), not cut by the image border, gets no lamps: its face is mostly hidden (a far car in a row).
    vehicle_min_face_share: float = 0.3
    #: A vehicle cut by a nearer one beside it (the car in front in a parked row): the end face's inner
    #: edge is looked for from this share of the face's width from the cut on (a strip of the face shows).
    vehicle_cut_min_strip: float = 0.1
    #: A lamp box at least ``vehicle_lamp_slope_min_px`` wide whose depth changes by more than this
    #: many metres per metre across it lies on a receding side face (or across an edge): no lamp.
    vehicle_lamp_max_slope: float = 1.2
    vehicle_lamp_slope_min_px: int = 6
    #: Lamps are rear lamps when red by day, or when their departure from the paint's colour (RGB, 8-bit)
    #: leans to red: red minus the larger of green and blue departures above this fraction of its length
    #: (a red lamp in shade or seen far away; a white lamp on blue paint departs evenly in red and green).
    vehicle_rear_red_share: float = 0.2
    #: Plausible height (m above the ground) of a vehicle body's top edge.
    vehicle_body_top_m: tuple[float, float] = (0.6, 1.2)
    #: Typical body-top height (m), used where the silhouette cannot tell (narrow or occluded faces).
    vehicle_body_top_typical_m: float = 0.9
    #: A found body top is moved down past the lid seen over the end face (rows whose depth is more than
    #: ``vehicle_lid_tol_m``, +3 % of the depth, beyond the face's), at most ``vehicle_lid_max_m`` (0: off).
    vehicle_lid_tol_m: float = 0.3
    vehicle_lid_max_m: float = 0.3
    #: End faces narrower than this (pixels) take the typical body top.
    vehicle_small_face_px: int = 24
    #: A column of a vehicle's cabin band most of whose pixels lie within this many levels of the
    #: paint is a pillar: the band's panes part there (0: at the end face's edge only).
    vehicle_pillar_paint_diff: float = 20.0
    #: A vehicle pane on a face of at least this many pixels per metre (at its depth; 15: nearer than
    #: about 30 m at 512x256) loses its bottom rows and side columns of body (``vehicles._body_trim``):
    #: a near car's cabin band runs over the sunlit top of its body and beside the cabin.
    vehicle_pane_body_min_ppm: float = 15.0
    #: A body pixel there has the paint's hue: its colour over its channels' sum within this much (a share
    #: of the sum, per channel) of the paint's (0: the trim off).
    vehicle_pane_body_tol: float = 0.04
    #: ... on a paint whose colour over its sum spreads at least this much across the channels (a share of
    #: the sum; a grey or white car's body has the glass's hue).
    vehicle_pane_body_chroma: float = 0.1
    #: A near car's pane (``vehicle_pane_body_min_ppm``) of glass darker than its paint takes the row below it
    #: where most of its bottom columns there lie within this share of the glass's departure from the paint of
    #: the glass's colour (``vehicles._glass_below``; 0: off).
    vehicle_pane_glass_below_share: float = 0.4
    #: An end face laid out from its inner edge (its outer edge hidden by a nearer object): that edge,
    #: found from depth, moves in by up to this share of the face's width to the pillar -- the shading
    #: step in the cabin rows (glass up to ``vehicle_pillar_rows_m`` above the body top) where end and
    #: side pane meet (``vehicles._pillar_edge``); only where the body rows show no shading step and the
    #: pillar (0.1 m) spans at least ``vehicle_pillar_min_px`` pixels (a far car's pane edges step as much).
    vehicle_pillar_reach: float = 0.3
    vehicle_pillar_rows_m: float = 0.45
    vehicle_pillar_min_px: int = 4
    #: A vehicle light at least 0.5 confident gets 0.5 + 0.5 sigmoid(bias + weights . features)
    #: (``vehicles._rescore``; docs/proposals.md, "Ninth pass: vehicle confidence"). Lamps: ring contrast
    #: (levels / 40, at most 3), both lamps of the pair stand out, a sliver beside the cut, ln pixels (at
    #: most ln 9; under 3 px across, at most 3 px per pixel across). Panes: ring contrast, the end pane (not
    #: the side one), ln pixels, lamps on the vehicle, a side pane of a vehicle the image border cuts
    #: (eleventh pass: vehicle confidence at 2048x1024 -- 1 tight of 15 such panes at >= 0.9, seeds 0-5,
    #: both sizes; since the panes part at pillars, 38 of 49 match at IoU >= 0.5: twelfth pass).
    #: A logistic fit for "IoU >= 0.7, right class" on seeds 0-2 at 512x256 and 2048x1024, bias then
    #: raised by 1.5 (lamps 2.0: the editor benchmark on seeds 0-2). Panes: refitted in the twelfth pass for
    #: "IoU >= 0.5" (what keeps a car's group whole in the editor), bias as fitted: a pane's pixels count
    #: 4x more than before, its being the end pane next to nothing (docs/proposals.md, "Twelfth pass:
    #: whole cars at the slider"). Panes refitted again with a sixth feature, the band parted at a pillar
    #: (paint-coloured columns between runs of glass: the pane's place seen, not laid out from the end
    #: face's edge), after the far panes' bottom row was fixed (docs/proposals.md, "Twelfth pass: far
    #: cars' panes").
    vehicle_lamp_conf_bias: float = -6.2
    vehicle_lamp_conf_weights: tuple[float, float, float, float] = (2.08, 1.05, -0.69, 2.8)
    vehicle_pane_conf_bias: float = -2.71
    vehicle_pane_conf_weights: tuple[float, float, float, float, float, float] = (0.93, 0.23, 0.49, 0.72, -2.38, 1.34)
    #: A far vehicle cut by the car in front with no lamp found gets its inner lamp's visible part at the cut
    #: laid out from the geometry (``vehicles._cut_lamp``; docs/proposals.md "Twentieth pass: vehicle lamps at
    #: 512x256"), at this confidence, not rescored: about half of them are right, so under the editor's slider
    #: (0.9); 0: off.
    vehicle_cut_lamp_conf: float = 0.55
    #: ... on vehicles whose whole lamp (0.15 m) is under this many pixels tall (a taller lamp's part at the cut
    #: is more than the one column laid out, and the sliver rules look for it by its colour).
    vehicle_cut_lamp_max_px: float = 2.5
    #: ... on vehicle instances from this many pixels (under ``vehicle_min_area_px`` only this lamp is looked for).
    vehicle_cut_lamp_min_px: int = 8
    #: ... on the rows whose pixel centres lie this high above the ground (m; a lamp's middle 0.07-0.22 m under
    #: a body top of 0.8-0.95 m), ...
    vehicle_cut_lamp_h_m: tuple[float, float] = (0.655, 0.805)
    #: ... when the end face's strip beside the cut holds at least this many pixels of the lamp (its inner edge
    #: ``vehicle_lamp_cols_m[0]`` in from the face's inner edge, where a side face this long (m) ending at the
    #: silhouette's inner end starts), ...
    vehicle_cut_lamp_vis_px: float = 0.75
    vehicle_cut_lamp_length_m: float = 4.3
    #: ... and a pixel of it departs from every blend of the occluder's colour and the paint by this many 8-bit
    #: levels (largest channel).
    vehicle_cut_lamp_blend_levels: float = 4.0
    #: ... a rear lamp when what the blend leaves of it is darker or leans red by more than this (8-bit levels).
    vehicle_cut_lamp_red_levels: float = 5.0

    # --- building windows
    #: A pixel is window-like when its luminance is below this fraction of the local wall luminance.
    window_dark_ratio: float = 0.72
    #: ... or when its chromaticity (Lab a, b; 8-bit units) is this far from the wall's (tinted glass).
    window_chroma_delta: float = 6.0
    #: Window height bounds (m) when depth is known (a receding facade foreshortens widths, not heights).
    window_height_m: tuple[float, float] = (0.45, 4.0)
    #: ... except the lower bound for a blob cut by the frame or by something in front (a car, a tree):
    #: its visible part can be any height.
    window_cut_any_height: bool = True
    #: Smallest window blob (pixels; was 6: at 512x256 a far pane is 1 px wide and 3-5 px tall, and
    #: from 1024 px up the candidates' 2x2 opening removes smaller specks anyway).
    window_min_area_px: int = 3
    #: ... and a window of fewer pixels than this is at most this confident (kept at 0.5, not taken by
    #: the editor's slider at 0.7 or 0.9: a few pixels say little).
    window_tiny_px: int = 6
    window_tiny_max_confidence: float = 0.6
    #: A window that keeps under this share of its pixels (or under ``window_tiny_px``) when the proposals
    #: are painted (the lights proposed before it -- signs, vehicle lamps, an overlapping window -- own
    #: contested pixels) keeps at most ``window_tiny_max_confidence``: what is proposed is a sliver its
    #: score was not judged on (0, with the tiny rule, caps only slivers under ``window_tiny_px``).
    window_min_painted_share: float = 0.5
    #: Fill of the window blob's bounding box (rectangularity) below which it is rejected.
    window_min_fill: float = 0.55
    #: ... counting only the box's pixels not hidden by something in front (not building, not sky).
    window_fill_unhidden: bool = True
    #: Leave the 1-px rim of what differs out of the wall estimate too (pixels mixing pane and wall).
    window_wall_rim: bool = False
    #: Share of wall pixels a box needs for its local wall estimate (else the coarser scale decides).
    window_wall_min_share: float = 0.08
    #: A wall (facade plane) more than this share of which differs from the wall reference gets its
    #: own reference (the mode of its colour: a narrow building between wider ones of other colour).
    window_rereference_share: float = 0.5
    #: ... kept when the share of that wall that differs drops to this fraction of before or less.
    window_rereference_keep: float = 0.65
    #: Leave building pixels beside sky or foliage (blended with them) out of the candidates (off: it
    #: loses more panes behind trees than it removes false ones at 512x256).
    window_skip_border: bool = False
    #: A blob darker than the wall by a ratio above ``window_shadow_ratio`` and within this chroma
    #: distance (Lab a, b) of it is the wall in a cast shadow, not a pane (0 turns the test off).
    window_shadow_chroma: float = 3.0
    window_shadow_ratio: float = 0.3
    #: ... and within this chroma distance when it runs down to the facade's foot (a pane has a sill;
    #: shade, lit by the blue sky only, drifts further from the wall's colour).
    window_shadow_chroma_footed: float = 10.0
    #: ... judged only on blobs of at least this area on the wall (m^2, with depth): a cast shadow is
    #: large; a smaller dark grey blob is a pane's part or a far pane with a dark interior (a whole pane
    #: of 1.2 x 2 m is 2.4 m^2: docs/proposals.md "Eighteenth pass: windows at 512x256"; 1.0 before).
    window_shadow_min_m2: float = 3.5
    #: Erode-and-split attempts on a blob that fails the fill or size test (joined panes).
    window_split_steps: int = 2
    #: ... first, such a blob is cut below (above) the rows at its top (bottom) that hold at least this share
    #: of its width: a fascia or lintel band a floor's panes hang from (windows._band_split; docs/proposals.md
    #: "Eighteenth pass: windows at 512x256"; 0: off).
    window_band_split_share: float = 0.75
    #: ... into parts alike in size, the largest at most this many times the smallest in area: a floor's
    #: panes (the streets' splits are within 2.1x); a wedge of wall beside a pane's flecks is not (0: any).
    window_band_part_ratio: float = 4.0
    #: A blob too large for a window of which at least this share is one colour is a wall piece the
    #: wall reference missed; its pixels differing from that colour are its panes (0: off).
    window_blob_wall_share: float = 0.5
    #: ... its colour the mode of a histogram of its log luminance in bins this share of the window
    #: threshold wide (the width of the "near the mode" window: a shaded wall spreads over narrower bins).
    window_blob_mode_step: float = 0.5
    #: ... or, short of that share, where a second colour of wall lies on the piece -- a cast shadow over
    #: it (or sun over a shaded one): a window threshold or more darker (lighter) than the mode, of the
    #: wall's hue (chroma within ``window_chroma_delta``), near at least this share of the blob -- what
    #: differs from both colours, when the two fill ``window_blob_wall_share`` and that is two parts or
    #: more holding ``window_blob_second_pane_share`` of the blob (windows._shadow_colour; 0: off).
    window_blob_second_share: float = 0.1
    window_blob_second_pane_share: float = 0.15
    #: A blob kept as one window splits into the parts that differ from its own colour (as a wall piece's,
    #: above) when at least this many of them are each at least half its height: a row of panes on a
    #: face the wall reference missed (windows._panes_side_by_side; 0: off).
    window_blob_row_min_panes: int = 3
    #: Windows whose centres lie within this height (m) of each other form one floor.
    window_floor_tol_m: float = 0.6
    #: Window groups (window_groups._building_end): a floor's step between neighbouring panes at least this many
    #: times its neighbouring steps, in image columns (a ratio, no unit), over a gap of visible wall blank on
    #: the other floors where their steps are as many times theirs, is a building's end: the floor is cut
    #: there and not joined across it (docs/proposals.md "Sixteenth pass: window groups at 512x256"; inf: never).
    window_end_px_ratio: float = 2.0
    #: Window groups (window_groups._join_inside_panes): a single pane left inside another group's span along
    #: its floor (in the gap between two neighbouring panes of it) joins that group when its centre row lies
    #: within this share of the neighbouring panes' median height (rows) of the straight line through their
    #: centres in the image, in their wall colour and on their plane (docs/proposals.md "Sixteenth pass: single
    #: panes inside their floor"; 0: never).
    window_inside_row_tol: float = 0.3
    #: A blob too large or ragged for one window is cut where its mean departure from the wall over a
    #: column (row, for a tall blob) dips below this fraction of the peaks either side (0: never, the
    #: default: it gains 2 % recall at 512x256 on the hard street and loses 2 % at 2048x1024).
    window_gap_contrast: float = 0.0
    #: A blob is cut where a run of its columns (rows) holds under this share of its height (width)
    #: with fuller ones on both sides: panes joined by a frame or a sill line (0: never).
    window_gap_occupancy: float = 0.25
    #: A blob of at least ``window_row_min_panes`` pieces at most ``window_row_pane_max_px`` wide, where
    #: its departure from the wall over a column dips below this fraction of the peaks either side, is a
    #: receding row of panes merged by their blur: cut there (windows._row_split; 0: never).
    window_row_gap_contrast: float = 0.8
    window_row_min_panes: int = 2
    window_row_pane_max_px: int = 3
    window_row_pane_max_h_px: int = 16
    #: ... each piece's width judged without its edge columns under ``window_unblur_ratio`` of its
    #: strongest column (a pane's blur into the wall beside it, the dim glass of a dark pane next to a
    #: lit one), and kept with one such column a side at most, for ``_unblur`` to take off after the
    #: grid (docs/proposals.md "Fifteenth pass: windows at 512x256").
    window_row_trim_faint: bool = True
    #: ... judged on a blob kept as one window that spans at least ``window_row_min_m_per_px`` of wall
    #: (m, from its depth) per pixel column and is longer along its wall than ``window_height_m[1]``,
    #: or spans ``window_row_wall_m_per_px`` per column.
    window_row_min_m_per_px: float = 0.5
    window_row_wall_m_per_px: float = 1.0
    #: A window at most ``window_row_pane_max_px`` wide loses an edge column whose mean departure from
    #: the wall is under this share of its strongest column's: its pane's colour bled there (0: off).
    window_unblur_ratio: float = 0.5
    #: ... and so does a wider one (a pane's edge blurred into the wall's next column: 2048x1024).
    window_unblur_any_width: bool = True
    #: A window at most ``window_row_pane_max_px`` wide, after its end rows are trimmed, loses its edge
    #: columns under this share of its strongest column's, as many a side as there are: a far 1-px pane
    #: shown in 3 columns by its blur (windows._unblur_narrow; 0: off).
    window_unblur_narrow_ratio: float = 0.55
    #: ... and so does a window 2 to ``window_row_pane_max_px`` wide over this many times the size of the
    #: panes around it (a ratio: pixels x depth^2 against the median of its six nearest windows at its
    #: depth, any wall), down to their median width: a far pane and its blur on a wall too short of windows
    #: for the floor-mates' test (0: off; windows._oversized_narrow_off).
    window_narrow_oversized_ratio: float = 1.3
    #: A window over this many times the size of the panes around it (a ratio, as
    #: ``window_narrow_oversized_ratio``), they at most 2 px wide and it twice as wide and a pixel, above the
    #: ground floor, mostly darker than the wall by under twice the window threshold (shade, not glass), is
    #: replaced by its largest part brighter by twice the threshold (a lit pane), else dropped (0: off;
    #: windows._shaded_patches).
    window_shaded_patch_ratio: float = 1.8
    #: A window on or touching a shaded patch windows._shaded_patches dropped, at least this share of it
    #: darker than the wall by the window threshold and none of it brighter by twice it, goes with it: the
    #: same shadow in pieces (0: off).
    window_shaded_patch_overlap: float = 0.5
    #: A window 3 px wide or more over this many times the size of the panes around it (a ratio, as
    #: ``window_narrow_oversized_ratio``), they at most 2 px wide, whose columns' strongest departure dips
    #: between two peaks to under ``window_split_dip_ratio`` of the weaker, is cut in two at the dip: two far
    #: panes a column apart merged by their blur (0: off; windows._split_two_panes).
    window_split_oversized_ratio: float = 2.0
    #: The dip of windows._split_two_panes, a share of the weaker peak's departure (0: off).
    window_split_dip_ratio: float = 0.4
    #: A window of kind ``window`` at least this many times as wide as the panes around it (their median
    #: width, px: the six nearest windows at its depth, any wall) loses its edge columns that read as wall
    #: -- mean departure under ``window_wall_columns_dev`` window thresholds and half its strongest
    #: column's, the fainter end first, two columns left at least: a pane's hull that took in a wall stripe
    #: or its sill's steps (0: off; windows._wide_wall_columns_off).
    window_wall_columns_width_ratio: float = 1.3
    #: ... the departure (window thresholds) under which such an edge column reads as wall.
    window_wall_columns_dev: float = 1.3
    #: ... and only when those columns are at least this share of its width: a wide pane's frame is a
    #: column or two of it, and its glass needs them (0: any).
    window_wall_columns_min_share: float = 0.2
    #: ... and only on a window at least this many rows tall (px): a shorter window's columns are too few
    #: pixels to tell a wall stripe from glass, and its blur columns are for windows._oversized_narrow_off.
    window_wall_columns_min_rows: int = 20
    #: ... and only on a window under this many times its neighbours' median width (0: no bound): a window
    #: far wider than the panes around it is a band or a shop front, not a pane's hull -- trimmed to its
    #: face it fills that face (2048x1024 lights seed 1's 44x71 office band: its face over the 40 % cap).
    window_wall_columns_max_width_ratio: float = 3.0
    #: A window of kind window 3 px wide and ``window_sill_rows_min_rows`` tall or more, over this many times its
    #: neighbours' size and over this many times their median height (windows._neighbour_ratios; 0: off),
    #: loses its end rows that depart from the wall beside it, in the two columns either side off every
    #: window, as much as in it (``window_sill_rows_side_ratio`` of it), at most a quarter of its rows:
    #: a sill or lintel band running on past the pane (windows._sill_rows_off; 2048x1024 lights seed 0's
    #: 5x39 pane with two sill rows).
    window_sill_rows_ratio: float = 1.15
    #: ... the share (0-1) of a row's mean departure in the window that each side's must reach.
    window_sill_rows_side_ratio: float = 0.8
    #: ... and only on windows this many rows tall or more (px): 512x256's far panes and their blur (20-37
    #: rows, 1-13 px wide) are left as they were.
    window_sill_rows_min_rows: int = 30
    #: ... and only under this many times the neighbours' median height (0: no bound): the rows trimmed are
    #: a quarter at most, so a pane with its sill is at most 1.33x as tall as panes like it; a window far
    #: taller is another kind of pane, or several (held out 2048 lights seed 5's 10x87 pane, 2.6x: 0.94 ->
    #: 0.72 trimmed).
    window_sill_rows_max_ratio: float = 1.5
    #: A window 1 px wide beside another window of its wall (half its rows at least beside it) whose mean
    #: departure from the wall is under this share of that window's strongest column's is dropped: the
    #: other's glass blurred into the wall, not a pane (windows._blur_columns_off; 0: off).
    window_blur_column_ratio: float = 0.33
    #: ... or, on a blob whose own wall colour the smooth reference missed (windows._blob_panes found it:
    #: a face of its own colour, all of it candidate), under this share measured against that colour
    #: (windows._own_colour_dev: a far pane's blur between two others on a bluish gable face; 0: off).
    window_blur_own_ratio: float = 0.25
    #: A window grows by the rows above its top / below its bottom that depart from the wall by at least
    #: ``window_extend_dev`` of the window thresholds over two thirds of its columns, on mean
    #: ``window_extend_side_ratio`` x the departure of the columns beside it (the rest of its pane:
    #: glass below a curtain band or a reflection that departs from the wall less; 0: off).
    window_extend_dev: float = 0.6
    window_extend_side_ratio: float = 1.5
    #: A window at most ``window_mates_short`` x the height its floor-mates' lintel and sill lines give at
    #: its centre (half its mates, two at least, with their ends on those lines within
    #: ``window_mates_fit_px``), one end on its line, grows to the other line by rows departing from the
    #: wall by ``window_mates_dev`` (mean, in window thresholds): a pane found by its band alone (0: off).
    window_mates_short: float = 0.75
    window_mates_fit_px: float = 1.5
    window_mates_dev: float = 0.3
    #: A window grows to the cross line (a row departing by the window thresholds over two thirds of its
    #: columns: a sill, the bottom rail) that a line of its own edge column (each pixel by the thresholds)
    #: runs to from its end, within a pane's height (``window_tall_keep_m``), the glass between departing by
    #: ``window_mates_dev``: a pane found as its band, outlined by its frame (False: off).
    window_frame_ends: bool = True
    #: Two windows of one floor whose gap is not wall -- each line across it departs from the wall by
    #: ``window_split_gap_dev`` of the window thresholds (a frame bar, faint glass; ``window_extend_dev``'s
    #: value: glass beyond a pane's band) or is covered by something in front -- and, side by side, at
    #: most ``window_split_gap_m`` on the wall (2 px at least; covered: both parts' width; one above the
    #: other: both parts' height), and whose union box is within
    #: ``window_split_size`` x their floor-mates' median pane (a pixel's allowance, half along the split)
    #: are one pane split in parts (0: off).
    window_split_gap_m: float = 0.15
    window_split_gap_dev: float = 0.6
    window_split_size: float = 1.2
    #: A window at most ``window_side_thin`` x the median width of its nearest mates (same wall; same
    #: floor with rows overlapping by ``window_side_overlap``, or same column) and at least
    #: ``window_side_tall`` x their height grows sideways by the columns of its pane that depart from
    #: the wall by ``window_extend_dev`` (mean, and on half its rows), up to ``window_side_cap`` x the
    #: mates' width: a receding pane found as its frame's side or a reflection strip (0: off).
    window_side_thin: float = 0.5
    window_side_tall: float = 0.8
    window_side_overlap: float = 0.6
    window_side_cap: float = 1.2
    #: ... each column taken departing at least this share of the last one (glass is even, a blur fades).
    window_side_flat: float = 0.7
    #: ... for a window at least this wide (px; a 1-px pane's blur beside it looks like faint glass).
    window_side_min_px: int = 2
    #: Blob pixels nearer than the wall in their image column (read 2 px above and below the blob) by
    #: this (m; 0: no test) and this share of the depth jut out of it: awnings, balcony slabs, their
    #: undersides -- not glass (windows._ledge_split). A blob mostly nearer and lower than
    #: ``window_ledge_keep_m`` is dropped (a dormer's pane stands before its roof, but is taller).
    window_ledge_step_m: float = 0.3
    window_ledge_rel: float = 0.05
    window_ledge_min_share: float = 0.2
    window_ledge_keep_m: float = 0.8
    #: ... not judged within this share of the image width of anything in front (a tree, a pole, a
    #: car) when that is over 2 px (the reads' own standoff): a depth map bleeds their depth over about
    #: that width (a depth network's or a stereo matcher's; twice a bleed sigma of 0.25 % of the width:
    #: 10 px at 2048x1024, 2 at 512x256).
    window_ledge_bleed_frac: float = 0.005
    #: A final window at most ``window_strip_max_px`` wide and three times as tall that spans less than
    #: ``window_min_width_m`` of its wall (from the wall's depth either side; 0: no test) is a downpipe, a
    #: crease or a pilaster's side, not a pane -- unless something in front cuts it at a side
    #: (windows._strip_width_m).
    window_min_width_m: float = 0.25
    window_strip_max_px: int = 3
    #: A final window at least ``window_soffit_aspect`` times as wide as it is tall (px; 3 rows at least) is a
    #: balcony soffit seen from below or a slab's face, not a pane, when its depth says its face is far from
    #: vertical: down each column its height above the ground (from the depth and the camera) falls per row
    #: by under ``window_soffit_tilt`` of the z / fy a vertical wall's does (a ratio: ~1 on a wall, ~0 on a
    #: horizontal face; the median over its columns; 0: no test; windows._soffit_like). docs/proposals.md
    #: "Nineteenth pass: false windows on balcony soffits".
    window_soffit_aspect: float = 1.5
    window_soffit_tilt: float = 0.45
    #: ... and a window at least as wide as it is tall (4 rows at least) under ``window_soffit_square_tilt``:
    #: a pane's shape, so only a face read as nearly horizontal (true panes that size read 0.35 and up).
    window_soffit_square_tilt: float = 0.2
    #: A final window touching the frame's top, at least ``window_wedge_min_px`` px wide and tall, whose convex
    #: hull fills at most ``window_wedge_hull_fill`` of its box while it fills ``window_wedge_mask_fill`` of its
    #: hull or more, one of whose rows (columns) spans ``window_wedge_base`` of the box's width (height) and
    #: ``window_wedge_one_colour`` of whose pixels lie within the window threshold of its median luminance -- a
    #: solid triangle of one colour: a face in shade under a roof's or a gable's slope -- is not a pane, whose
    #: image has vertical sides and a top and a bottom along its wall (shares; 0: no test; windows._wedge_like).
    #: docs/proposals.md "Twentieth pass: the 40 % lit share".
    window_wedge_min_px: int = 10
    window_wedge_hull_fill: float = 0.62
    window_wedge_mask_fill: float = 0.8
    window_wedge_base: float = 0.8
    window_wedge_one_colour: float = 0.7
    #: The pane in such a wedge: its pixels off the wedge's median log luminance by more than the window
    #: threshold, their largest part (8-connected) filled to its hull, at least ``window_wedge_pane_min_px`` px
    #: wide and tall with the wedge either side, filling half its box and under ``window_wedge_pane_share`` of
    #: the wedge's pixels, replaces the wedge (windows._wedge_pane; 0: the wedge goes whole; docs/proposals.md
    #: "Twenty-first pass: the 1.5x rule"). ``window_wedge_mask_fill`` was 0.85 before that pass: a wedge whose
    #: hull a thin leg of wall at its foot widens (2048x1024 lights seed 0) fills 0.83 of it.
    window_wedge_pane_min_px: int = 4
    window_wedge_pane_share: float = 0.3
    #: A window must differ from the wall in a ring this wide (pixels) around it (0: no test).
    window_ring_px: int = 2
    #: Without depth, a building region whose luminance departs from its 3x3 mean (1.4826 x the median
    #: absolute deviation, in log luminance) by more than ``window_texture_mad`` x the window threshold
    #: (-ln ``window_dark_ratio``) is textured (brick, stone): its features are averaged over the rows its
    #: texture repeats in (a brick course's few pixels, at most ``window_texture_cell_px``; a pane is a cell
    #: of metres) before the wall reference and the candidates (windows._texture_walls; 0: no test; with
    #: depth nothing changes).
    window_texture_mad: float = 0.6
    #: ... judged on building regions of at least this share of the image (a small piece is mostly edges).
    window_texture_min_share: float = 0.005
    window_texture_cell_px: int = 12
    #: A blob kept as a window of which at least ``window_trim_wall_share`` has the colour of the wall
    #: around it (windows._wall_coloured) is glass and a piece of that wall: its parts of other colours
    #: filling ``window_trim_min_fill`` of their box are judged instead (1: no test).
    window_trim_wall_share: float = 0.2
    window_trim_min_fill: float = 0.8
    #: ... on an upper floor too (the rule above is a shop front's on the ground floor), but there only when
    #: what is not wall is one such part holding at least ``window_trim_upper_share`` (a share of the blob's
    #: pixels) of it: a pane and a strip of plain wall beside it that the reference steps under (hard street
    #: 512x256 seed 0, x 413-422: 0.95, IoU 0.49), not a pane whose reflection takes the wall's colour over
    #: most of it (docs/proposals.md "Sixteenth pass: windows at 512x256 -- a strip of wall beside a pane").
    window_trim_any_floor: bool = True
    window_trim_upper_share: float = 0.5
    #: Shop fronts: glazing whose bottom is at most this high (m above the ground) and at least this tall (m).
    window_shop_max_sill_m: float = 1.0
    window_shop_min_h_m: float = 1.6
    #: A pane this far behind the plane of the wall below it (share of its depth, min and max; the
    #: plane fitted over this band of metres below the pane) is a dormer's (kind ``dormer``, not a
    #: facade window; (0, 0): off).
    window_dormer_set_back: tuple[float, float] = (0.05, 0.4)
    window_dormer_below_m: tuple[float, float] = (1.0, 4.0)
    #: Office floor bands: glazing at least this many times wider than tall (m).
    window_band_min_aspect: float = 3.5
    #: Fewest columns (px) of a window whose top and bottom edges' slope gives its wall's direction
    #: (:func:`windows._along_wall_m`): a narrower one is measured face on.
    window_band_edge_px: int = 6
    #: ... such a window at least this many times longer along its wall than tall (m), its bottom at
    #: least ``window_band_min_sill_m`` above the ground (wide glazing lower down is a shop front's), is
    #: an office floor band (0 edge px: off).
    window_band_wall_aspect: float = 3.0
    window_band_min_sill_m: float = 3.0
    #: ... and at least this tall (m) on its wall (the second: when the frame's top or bottom row cuts it):
    #: taller than a pane of a window row, which a wall seen at an angle can stretch along it.
    window_band_min_h_m: float = 2.2
    window_band_cut_min_h_m: float = 1.0
    #: Top and bottom edges whose directions on the wall differ by more than this (degrees): the one
    #: nearer the wall's direction from the depth around the window is taken.
    window_band_edge_agree_deg: float = 15.0
    #: An empty facade-grid cell is a window when this share of its pixels differs from the wall by
    #: half the window thresholds.
    window_cell_min_share: float = 0.5
    #: A window wider than this many times the wider of its floor neighbours spans bays (merged panes;
    #: widths shrink fast down a receding facade, so not 1.5).
    window_wide_ratio: float = 1.9
    #: A window taller than 1.5x its wall's median window height with no floors to cut it along is
    #: kept (for the area rule, ``window_max_median_ratio``, against whole panes) when it is at most
    #: this tall (m; 0: always dropped): on a wall of a few windows the height median is often a
    #: fragment's, while a blob most of a storey tall is a gable, a doorway or a shadow, not a pane.
    window_tall_keep_m: float = 2.5
    #: Two windows of one floor side by side (each >= 3 px wide) with something in front (not building or
    #: sky) covering the columns between them, no wider than both, are the two parts of one pane cut by a
    #: pole, a post or a trunk: joined when their rows overlap by at least this share of the taller one
    #: (0: never; windows._join_across_occluders, docs/proposals.md "Tenth pass: half-panes").
    window_join_min_overlap: float = 0.6
    #: ... and the joined box is at most this times as wide as the median of its wall's other windows on
    #: the floor near its depth (two whole panes with a post in front of the wall between them are wider).
    window_join_max_width: float = 1.3
    #: ... and two windows touching end to end (boxes at most a row apart or overlapping by under half the
    #: shorter, masks apart), left and right edges in line within a pixel: a pane's upper sash and its
    #: lower part (the same height caps).
    window_join_sash: bool = True
    #: ... with depth, two parts side by side or one above the other whose median depths differ by over
    #: 5 % still join when the wall just beyond their far sides does not: a post's depth bleeds into the
    #: glass beside it (docs/proposals.md "Eleventh pass: parts of a pane either side of a post").
    window_join_facing: bool = True
    #: Windows cover at most this share of their building region (the least confident beyond it are dropped).
    window_max_lit_share: float = 0.4
    #: A floor's windows belong to another facade (another windows_group) where the wall around them
    #: changes by this much (log luminance; Lab chroma, 8-bit units) or their height by this fraction.
    window_block_lum: float = 0.3
    window_block_chroma: float = 8
    window_block_height: float = 0.5
    #: Window groups (window_groups._shadow_pair): two parts of one floor whose wall colours differ in log
    #: luminance by more than the first and at most the second, of one hue (chroma within
    #: ``window_chroma_delta``), two panes each, are joined as one wall in sun and in a cast shadow when the
    #: rest of the join's tests pass: on one plane by the wall's depth beside the panes, the gap's wall of
    #: either colour, the gap at most ``BLANK_STEPS`` x the smaller part's step. (0, 0): off.
    window_group_shadow_lum: tuple[float, float] = (0.6, 1.0)
    #: Window groups (window_groups._gap_is_wall): the wall's depth between two panes is not judged within
    #: this share of the image width (px) of anything in front: its depth bleeds onto the wall beside it (a
    #: pole between two parts of one floor; docs/proposals.md "Eighteenth pass: windows at 512x256"; 0: judged
    #: everywhere).
    window_gap_bleed_frac: float = 0.005
    #: Box of the fine local wall estimate, as a fraction of the image width (the coarse box is 4x).
    window_wall_kernel_frac: float = 0.02
    #: Facades (wall planes) of a building region, with depth: wall directions binned by this many
    #: degrees (seen from above); a new wall where the plane's offset steps by this many metres (+1 %
    #: of the depth) or the wall colour by ``window_block_lum`` / ``window_block_chroma``.
    window_facade_angle_deg: float = 30.0
    window_facade_step_m: float = 0.3
    #: A cell of a wall's window lattice is proposed when this share of it shows that wall.
    window_cell_min_visible: float = 0.8
    #: ... at most this many pixels wide (a wider pane is found as a blob where there is one) and at
    #: most this many bays beyond the panes found, toward the vanishing point.
    window_cell_max_px: int = 3
    window_cell_max_extra_bays: int = 4
    #: A cell cut out of a blob too large for one window (regularise) takes the blob's run of columns that
    #: fill half the floor's rows and hold the cell's, when that run is at most this many times the cell's
    #: width and no window holds it: a pane wider than the bays its wall's other floors give (0: off;
    #: docs/proposals.md "Eighteenth pass: windows at 512x256").
    window_cell_grow: float = 2.0
    #: A window within a lattice cell's columns and under this share of the cell's pixels is a
    #: fragment of the cell's pane (its top rows, a fleck of it): the cell replaces it (0: off).
    window_cell_fragment_share: float = 0.6
    #: No window larger than this many times the median window of its wall (area on the wall).
    window_max_median_ratio: float = 1.5
    #: ... judged on walls with at least this many windows (fewer give no reliable median).
    window_median_min_count: int = 5
    #: ... unless its top is at most this high (m above the ground): ground-floor glazing larger than
    #: the windows above is a shop front (kind ``shop``; cars often hide its lower part).
    window_shop_max_top_m: float = 3.2
    #: ... also a final window of kind ``window`` larger than that ratio x the median window above the
    #: ground floor of its wall (three at least), else of those over its columns (widened by its width
    #: either side; two at least) at a depth within this share of its own (``windows._shop_fronts``).
    window_shop_above_depth_tol: float = 0.1
    #: No whole window smaller than this many times the median whole window of its wall (a
    #: fragment: a frame, half a pane, a fleck of wall); a pane's visible part is kept. 0: off.
    window_min_median_ratio: float = 0.33
    #: ... but a window at least this many pixels across both ways is judged against its floor's whole
    #: windows (two at least) when their median is smaller: a floor of small panes (windows._small_rule);
    #: a narrower piece is within one pane's blur.
    window_resolved_px: int = 3
    #: A window larger than ``window_max_median_ratio`` x its wall's median is cut where its departure
    #: from the wall over a column (row) dips below this fraction of the peaks either side (0: never).
    window_oversized_gap_contrast: float = 0.6
    #: A window the 1.5x rule drops is replaced by its panes where it dips at its floor's bay pitch and its
    #: floor-mates -- windows of its floor at its depth within this share -- say what a pane is: far panes
    #: merged by their blur (windows._pitch_cut; 0: off).
    window_pitch_cut_depth_tol: float = 0.15
    #: The score's weakest side (window_confidence.edge_contrast) is read along the window mask's own edge,
    #: not its box's outer rows and columns, for a mask filling at least this share of its box: a receding
    #: pane is a parallelogram, its box's outer rows mostly wall (docs/proposals.md "Sixteenth pass: windows
    #: at 512x256"; over 1: always the box's).
    window_edge_mask_min_fill: float = 0.75
    #: A window's final confidence (window_confidence.window_confidence): 0.5 + 0.5 sigmoid(bias + weights .
    #: window_confidence.score_terms: first confidence, log-luminance and chroma contrast to the wall in a
    #: ring around it over the window thresholds, clipped at 3, height in m clipped at 2.5, ln of its
    #: pixels, ln(1 + row-mates), ln(1 + column-mates), another window touching its box; fill of its box,
    #: m over 2 m tall, ground floor, share of things in front around it and touching its box, contrast
    #: of its box's weakest side), for windows at least 0.5 confident (the set kept at 0.5 is
    #: unchanged). A logistic fit on the synthetic streets' windows (seeds 0-2, default / hard /
    #: lights, 512x256 and 2048x1024; target: matched at mask IoU >= 0.7, no touch-up; ``python -m
    #: benchmarks.window_confidence --fit``), the bias raised by 1.0 for the editor's default slider
    #: (0.9): a false window costs two actions, a true one saves one (docs/proposals.md "Seventh pass",
    #: "Tenth pass: window confidence from the façade grid", "Eleventh pass: the slider"). Five
    #: weights: the seventh pass's rule; eight: the tenth pass's; 13: without the weakest side. All
    #: weights 0: the first confidence as it is.
    window_conf_bias: float = -5.98
    window_conf_weights: tuple[float, ...] = (2.21, 0.22, 1.20, 0.52, 0.31, 0.63, 0.87, -0.73,
                                              1.51, -2.64, -1.38, 1.41, -0.99, 0.92)

    # --- advertisements
    #: Saturation (HSV, 0..1) and minimum area (m^2) of a bright, saturated panel on a facade.
    ad_min_saturation: float = 0.4
    ad_min_area_m2: float = 1.0
    #: ... and its height (m; a shop's fascia sign is 0.3-0.8 m tall).
    ad_min_height_m: float = 0.3
    #: ... and the share of its convex hull it fills (a panel is a quadrilateral in the image).
    ad_min_hull_fill: float = 0.7
    #: Height above the ground (m) of a shop's fascia band, where a panel's bottom edge may lie to make it
    #: a shop sign under the size rules: over the shop front's glazing (2.2-3 m) and its awning, under
    #: the first floor's sills (docs/proposals.md "Fifteenth pass: shop signs on the lights street").
    ad_fascia_m: tuple[float, float] = (2.4, 4.5)
