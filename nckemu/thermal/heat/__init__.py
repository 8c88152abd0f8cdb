"""Heat identification: each sensor's temperature as a response to what the machine does (spindle
speed, axis motion, a switched input such as coolant) and to the room or a neighbour sensor, found
and judged on held-out data the way discovery judges the error's terms (docs/heat.md)."""
