"""The auv command: launch, record, play, depth, run, design, ident, gap."""
