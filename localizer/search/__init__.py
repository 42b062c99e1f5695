"""Finding the targets in a frame: the coarse row scan and its runs, and the candidate stacks that
pass the two-bar tests (thesis section 4.4, App. A).
"""
