# The fleet's image: `fleet` (simulator, launcher), `onboard` and `ground-cli`.
# One image for every service of compose.yaml; the command picks the role.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /app

# What `pip install .` needs, and nothing else (.dockerignore keeps the rest out).
COPY pyproject.toml README.md ./
COPY fleet ./fleet
COPY onboard ./onboard
COPY ground ./ground
COPY programs ./programs

# Installed as a user would (not editable), then each console script is run once, so a
# broken entry point fails the build rather than the fleet.
RUN pip install . \
    && fleet --help >/dev/null \
    && onboard --help >/dev/null \
    && ground-cli --help >/dev/null

# No process of the fleet needs root.
RUN useradd --system --no-create-home --shell /usr/sbin/nologin fleet
USER fleet

ENV FLEET_ZENOH_CONNECT=tcp/router:7447

CMD ["ground-cli", "--help"]
