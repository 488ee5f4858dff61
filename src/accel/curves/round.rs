//! Ray–tube intersection matching Embree's `ROUND_BSPLINE` curves (not yet written: issue 13).
