"""The S7 face: ISO-on-TCP (``server``) over a sans-IO session (``session``) that hands jobs to the
dispatcher (``dispatch``), which reads and writes the machine through two narrow protocols
(``datastore``)."""
