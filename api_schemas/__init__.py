"""Request and response models of the QuadSynth HTTP API (pydantic v2) and the binary wire format.

Kept apart from :mod:`service` so clients can import them without the server.
"""

from api_schemas.models import (
    Blob,
    CharacterIn,
    CharacterOut,
    CharacterWarning,
    ErrorDetail,
    ErrorResponse,
    GaitRange,
    Health,
    LibrariesResponse,
    LibraryDetail,
    LibraryStatus,
    LibrarySummary,
    Limits,
    LiveCharacter,
    LiveRequest,
    Lod,
    PackedRotations,
    Readiness,
    Skipped,
    SynthesizeRequest,
    SynthesizeResponse,
)

__all__ = ["Blob", "CharacterIn", "CharacterOut", "CharacterWarning", "ErrorDetail", "ErrorResponse",
           "GaitRange", "Health", "LibrariesResponse", "LibraryDetail", "LibraryStatus", "LibrarySummary",
           "Limits", "LiveCharacter",
           "LiveRequest", "Lod", "PackedRotations", "Readiness",
           "Skipped", "SynthesizeRequest", "SynthesizeResponse"]
