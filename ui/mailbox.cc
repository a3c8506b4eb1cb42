#include "ui/mailbox.h"

#include <QCoreApplication>

#if defined(__SANITIZE_THREAD__)
#define SAKER_TSAN 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define SAKER_TSAN 1
#endif
#endif

#ifdef SAKER_TSAN
#include <sanitizer/tsan_interface.h>
#endif

namespace saker::ui {
namespace {

QEvent::Type LetterType() {
  static const auto type = static_cast<QEvent::Type>(QEvent::registerEventType());
  return type;
}

}  // namespace

Mailbox::Letter::Letter() : QEvent(LetterType()) {}

void Mailbox::Sent([[maybe_unused]] const QEvent* letter) {
#ifdef SAKER_TSAN
  __tsan_release(const_cast<QEvent*>(letter));
#endif
}

void Mailbox::Received([[maybe_unused]] const QEvent* letter) {
#ifdef SAKER_TSAN
  __tsan_acquire(const_cast<QEvent*>(letter));
#endif
}

void Mailbox::send(Letter* letter) {
  // Everything the receiver reads was written above this line, on this thread.
  Sent(letter);
  QCoreApplication::postEvent(this, letter);
}

void Mailbox::customEvent(QEvent* event) {
  Received(event);  // before anything reads the event, its type included
  if (event->type() == LetterType()) static_cast<Letter*>(event)->run();
}

}  // namespace saker::ui
