"""The `lhd` command line: launcher, echo, benches."""
