"""Pages of the documentation generated from the code, so they cannot drift: the guide's and
README's tables (:mod:`.tables`) and one reference page per technique (:mod:`.technique_pages`),
checked by the docs tests. ``python -m shadowlab.docgen.tables --write`` brings them up to date.
"""
