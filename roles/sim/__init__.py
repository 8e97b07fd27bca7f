"""Simulation: the same cores on a network of our own making.

``simnet`` delivers datagrams and TCP streams in memory on a fake clock, so a whole match runs
in milliseconds and every byte is seen; ``faults`` decides loss, latency, jitter,
duplication, reordering, corruption and cuts per link, for that network and for the asyncio
shell alike.
"""
