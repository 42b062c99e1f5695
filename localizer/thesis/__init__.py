"""The thesis's own method (``method="thesis"``): its edge points, its test points (Tables 5.1-5.4)
and its pose equations (thesis section 4.7).
"""
