"""Analysis of a bending finger's recording: the driver's joint angle against the truth."""
