"""Agents from other frameworks run in sagebench's closed loop as they are (vlnce: habitat's Agent interface)."""
