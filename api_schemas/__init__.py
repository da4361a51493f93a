"""Request and response models of the QuadSynth HTTP API (pydantic v2).

Kept apart from :mod:`service` so clients can import them without the server.
"""

from api_schemas.models import Health, LibrariesResponse, LibrarySummary, Readiness

__all__ = ["Health", "LibrariesResponse", "LibrarySummary", "Readiness"]
