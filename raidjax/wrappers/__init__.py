"""raidjax in other people's learners: ``raidjax.wrappers.jaxmarl`` (a JaxMARL ``MultiAgentEnv``)
and ``raidjax.wrappers.gymnax`` (gymnax ``Environment`` views). Each imports its package, which
is an optional extra: ``pip install "raidjax[jaxmarl]"`` or ``"raidjax[gymnax]"``."""
