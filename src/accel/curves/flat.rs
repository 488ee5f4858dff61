//! Ray–ribbon intersection matching Embree's `FLAT_BSPLINE` curves (not yet written: issue 13).
