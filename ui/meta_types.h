#pragma once

// Engine types that travel in queued signals, declared once for every GUI header that uses
// them in a signal (the declaration must precede any use).

#include "core/util/status.h"

#include <QMetaType>

Q_DECLARE_METATYPE(saker::Status)
