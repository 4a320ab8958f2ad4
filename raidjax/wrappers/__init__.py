"""raidjax in other people's learners: ``raidjax.wrappers.jaxmarl`` (a JaxMARL ``MultiAgentEnv``)
and ``raidjax.wrappers.gymnax`` (gymnax ``Environment`` views). Each imports its package, which
is an optional extra: ``pip install -e ".[jaxmarl]"`` or ``".[gymnax]"`` in a raidjax checkout
(raidjax is not on PyPI)."""
