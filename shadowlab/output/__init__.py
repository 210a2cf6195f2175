"""Everything a run leaves for people to read: pictures (:mod:`.pictures`), plots
(:mod:`.pareto`), the one run-directory writer and the Jinja2 pages."""
