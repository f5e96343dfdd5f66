"""Local-view front ends of RatSLAM: turn an observation into a view-template id.

* :mod:`cansim.frontends.visual` - OpenRatSLAM's visual templates (camera images).
* :mod:`cansim.frontends.tactile` - the whisker-array tactile image of Ch.3 (Eq 3.1).

Both expose ``match(observation) -> TemplateMatch(template_id, is_new, error, relative_rad)``.
"""
