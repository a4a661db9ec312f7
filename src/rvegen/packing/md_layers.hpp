// Molecular-dynamics packing, the start of planar fibres: heights in layers.
//
// Fibres of a planar law that keep their orientation (or turn only in their plane) meet where
// their projections onto the plane cross, and the contact pushes them along the plane's normal
// only. Growing about random centres, they keep the order of their heights along that normal,
// and a stack of crossing fibres that winds once around a periodic box stops the growth (with
// random heights, long fibres jam very early). So these fibres start at heights that
// leave room for their full size:
//   1. a fibre's projection is its section through its axis (a cylinder lying in the plane is
//      symmetric about it), so two fibres can overlap only if their projections do (their
//      capsules of radius r (1 + pad) in the plane, a superset), and never when their heights
//      differ by at least the sum of their radii;
//   2. the box height H along the normal holds K = floor(H / T) layers of thickness T (the
//      largest diameter); largest first, each fibre takes a random layer that no fibre already
//      placed with a crossing projection holds, and is moved elsewhere in its plane (direction
//      kept) when every layer is taken there; after kMoves moves it tries places where it meets
//      at most kSlideFibres fibres of some layer and slides out of them in its plane (each
//      pushes it along the line of the axes' closest points by the overlap), which fills the
//      layers well beyond random placement; after kSlidesFirst such places, a place where
//      some layer holds at most kEvictFibres fibres that meet it is taken too: the fibre takes
//      that layer and those fibres go back to the queue to be placed anew (as in cuckoo
//      hashing). Crossing fibres push each other only along the normal, so the packing cannot
//      sort out a fibre left crowded: the evictions place the last fibres of nearly full layers
//      (without them, a handful of crowded fibres jammed long fibres short of a target they
//      reach with them). A fibre that still finds no room takes the least crowded
//      layer. The work is bounded: kSlideBudget slide places per fibre and kEvictShare of the
//      fibres evicted, in all, and kTimeShare of md.max_seconds, after which the fibres left go
//      on without slides or evictions. Where more than kCrowdedShare of the fibres find no
//      room (a target beyond what layers hold), the layers are built for sizes kShrink smaller,
//      down to kMinScale, and the packing grows from there;
//   3. a few sweeps move each fibre to a uniformly random height within the room its crossing
//      neighbours leave (exactly, on the periodic circle), so heights are not on a lattice where
//      there is room.
// Only cylinders (a coated, wavy or bent one by the straight cylinder it is packed in: its
// envelope or the bound of its chain) whose law confines their axes to a plane normal to a box
// axis are placed so; the others keep their random centres.
#pragma once

#include "rvegen/geometry/random.hpp"
#include "rvegen/packing/md_bodies.hpp"

namespace rvegen::md {

/// Sets the heights (and where a layer is full, the in-plane centres) of the planar fibres of
/// `bodies` as above; says after each try (a scale of the layers) how it went.
void layer_planar_fibres(const PackingSpec& spec, Random& rng, Bodies* bodies,
                         const ProgressFn& progress = nullptr);

/// Aligned fibres (growing in radius only, at full length; see md_bodies.hpp) along a box axis
/// where the box holds K = floor(H / L) >= 2 of the longest end to end: with random positions
/// along the axis two fibres can share a line only where their spans happen to be disjoint, so
/// each line holds about one fibre and the packing jams early (far below the target, for long
/// fibres of L about H / 2). Where one fibre per line would not fit (their sections would fill
/// more than 0.7 of the cross-section), the axis is cut into K slots of length H / K, equal
/// numbers of fibres go to each (in a random order), each placed at a uniform position within
/// its slot. Fibres of different slots never meet; each slot is packed as a layer of disks.
void slot_aligned_fibres(const PackingSpec& spec, Random& rng, Bodies* bodies);

}  // namespace rvegen::md
